// Volume down-sampling (block mean + geometry) and cropping.
#include <gtest/gtest.h>

#include "hpcm/volume.hpp"

using namespace hpcm;

namespace {

Volume ramp(Int3 dims) {
  Volume v;
  v.dims = dims;
  v.spacing = {0.5, 0.75, 2.0};
  v.origin = {-10.0, 20.0, 5.0};
  v.hu.resize(v.size());
  for (int z = 0; z < dims.z; ++z)
    for (int y = 0; y < dims.y; ++y)
      for (int x = 0; x < dims.x; ++x) v.hu[v.index(x, y, z)] = float(x + 10 * y + 100 * z);
  return v;
}

TEST(Volume, DownsampleBlockMean) {
  const Volume v = ramp({4, 4, 2});
  const Volume d = downsample(v, 2);
  ASSERT_EQ(d.dims, (Int3{2, 2, 1}));
  // Block (0,0,0) holds x in {0,1}, y in {0,1}, z in {0,1}: mean = 0.5 + 5 + 50.
  EXPECT_FLOAT_EQ(d.at(0, 0, 0), 55.5f);
  EXPECT_FLOAT_EQ(d.at(1, 0, 0), 57.5f);
  EXPECT_FLOAT_EQ(d.at(0, 1, 0), 75.5f);
  EXPECT_FLOAT_EQ(d.at(1, 1, 0), 77.5f);
}

TEST(Volume, DownsampleGeometry) {
  const Volume v = ramp({8, 6, 4});
  const Volume d = downsample(v, 2);
  EXPECT_DOUBLE_EQ(d.spacing[0], 1.0);
  EXPECT_DOUBLE_EQ(d.spacing[1], 1.5);
  EXPECT_DOUBLE_EQ(d.spacing[2], 4.0);
  // New voxel (0,0,0) is the centre of the first block: input index (0.5, 0.5, 0.5).
  EXPECT_DOUBLE_EQ(d.origin[0], -10.0 + 0.25);
  EXPECT_DOUBLE_EQ(d.origin[1], 20.0 + 0.375);
  EXPECT_DOUBLE_EQ(d.origin[2], 5.0 + 1.0);
  // Physical position of a down-sampled voxel = centre of its block in the input.
  const auto p = d.index_to_physical(3, 2, 1);
  const auto q = v.index_to_physical(6.5, 4.5, 2.5);
  for (int a = 0; a < 3; ++a) EXPECT_NEAR(p[a], q[a], 1e-12);
}

TEST(Volume, DownsampleKeepsCompleteBlocksOnlyEachAtItsVoxelsCentre) {
  // 5 x 7 x 3 voxels at f = 2: complete blocks 2 x 3 x 1; the last voxel row of x, of y and
  // of z belongs to no block. A partial block would have its voxels' centre off the grid.
  const Volume v = ramp({5, 7, 3});
  const Volume d = downsample(v, 2);
  ASSERT_EQ(d.dims, (Int3{2, 3, 1}));
  for (int y = 0; y < 3; ++y)
    for (int x = 0; x < 2; ++x) {
      double sum = 0, ci = 0, cj = 0, ck = 0;
      for (int k = 0; k < 2; ++k)
        for (int j = 2 * y; j < 2 * y + 2; ++j)
          for (int i = 2 * x; i < 2 * x + 2; ++i) sum += v.at(i, j, k), ci += i, cj += j, ck += k;
      EXPECT_FLOAT_EQ(d.at(x, y, 0), float(sum / 8));
      // The element's physical position is the mean position of the voxels it averages.
      const auto p = d.index_to_physical(x, y, 0);
      const auto q = v.index_to_physical(ci / 8, cj / 8, ck / 8);
      for (int a = 0; a < 3; ++a) EXPECT_NEAR(p[a], q[a], 1e-12) << "element " << x << "," << y;
    }
  // f = 3 on 7 voxels: blocks [0,3) and [3,6); voxel 6 is left out.
  const Volume t = downsample(ramp({7, 7, 7}), 3);
  EXPECT_EQ(t.dims, (Int3{2, 2, 2}));
}

TEST(Volume, DownsampleFactorOneAndErrors) {
  const Volume v = ramp({4, 5, 6});
  const Volume same = downsample(v, 1);
  EXPECT_EQ(same.hu, v.hu);
  EXPECT_EQ(same.dims, v.dims);
  EXPECT_THROW(downsample(v, 0), Error);
  try {
    downsample(v, 5);  // larger than the smallest dimension (4)
    FAIL() << "factor 5 accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("factor"), std::string::npos) << e.what();
  }
}

TEST(Volume, CropValuesAndOrigin) {
  const Volume v = ramp({6, 5, 4});
  const Volume c = crop(v, {1, 2, 1}, {4, 5, 3});
  ASSERT_EQ(c.dims, (Int3{3, 3, 2}));
  for (int z = 0; z < 2; ++z)
    for (int y = 0; y < 3; ++y)
      for (int x = 0; x < 3; ++x) EXPECT_EQ(c.at(x, y, z), v.at(x + 1, y + 2, z + 1));
  const auto o = v.index_to_physical(1, 2, 1);
  for (int a = 0; a < 3; ++a) EXPECT_DOUBLE_EQ(c.origin[a], o[a]);
  EXPECT_EQ(c.spacing, v.spacing);
}

TEST(Volume, CropRejectsBadBoxes) {
  const Volume v = ramp({6, 5, 4});
  EXPECT_THROW(crop(v, {0, 0, 0}, {7, 5, 4}), Error);   // beyond the volume
  EXPECT_THROW(crop(v, {3, 0, 0}, {3, 5, 4}), Error);   // empty
  EXPECT_THROW(crop(v, {-1, 0, 0}, {2, 5, 4}), Error);  // negative
}

TEST(Volume, ValidateRejectsBadVolumes) {
  Volume v = ramp({3, 3, 3});
  EXPECT_NO_THROW(validate_volume(v, "ct"));
  v.hu[4] = std::nanf("");
  EXPECT_THROW(validate_volume(v, "ct"), Error);
  v = ramp({3, 3, 3});
  v.spacing[1] = 0;
  EXPECT_THROW(validate_volume(v, "ct"), Error);
  v = ramp({3, 3, 3});
  v.hu.pop_back();
  EXPECT_THROW(validate_volume(v, "ct"), Error);
}

}  // namespace
