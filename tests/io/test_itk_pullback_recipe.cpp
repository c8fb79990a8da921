// The ITK recipe of docs/io.md and docs/slicer.md for the pull-back field, run with ITK's own
// classes (issue 32, item 3): the exported displacement_pullback_final (NIfTI and NRRD) in an
// itk::DisplacementFieldTransform, the input CT resampled by itk::ResampleImageFilter with a
// linear interpolator and default -1000, must give hpcm's deformed CT within 1 % rms of the
// change. No inversion: the field is already the resampling direction.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>

#include <itkDisplacementFieldTransform.h>
#include <itkImage.h>
#include <itkImageFileReader.h>
#include <itkLinearInterpolateImageFunction.h>
#include <itkNiftiImageIO.h>
#include <itkNrrdImageIO.h>
#include <itkResampleImageFilter.h>
#include <itkVector.h>

#include "hpcm/io.hpp"
#include "hpcm/tissue.hpp"

namespace fs = std::filesystem;
using namespace hpcm;

namespace {

const std::string kNifti = std::string(HPCM_SHARED_DATA) + "/abdomen-ct/abdomen_ct.nii.gz";

using CtImage = itk::Image<float, 3>;
using FieldImage = itk::Image<itk::Vector<double, 3>, 3>;

template <class TImage>
typename TImage::Pointer read(const std::string& path) {
  auto reader = itk::ImageFileReader<TImage>::New();
  // The IO named explicitly (this test does not register ITK's IO factories).
  if (path.size() > 5 && path.substr(path.size() - 5) == ".nrrd")
    reader->SetImageIO(itk::NrrdImageIO::New());
  else
    reader->SetImageIO(itk::NiftiImageIO::New());
  reader->SetFileName(path);
  reader->Update();
  return reader->GetOutput();
}

// The recipe: pull-back field -> DisplacementFieldTransform -> ResampleImageFilter on the input.
CtImage::Pointer warp_with_itk(const std::string& ct_path, const std::string& pullback_path) {
  CtImage::Pointer ct = read<CtImage>(ct_path);
  auto transform = itk::DisplacementFieldTransform<double, 3>::New();
  transform->SetDisplacementField(read<FieldImage>(pullback_path));
  auto resample = itk::ResampleImageFilter<CtImage, CtImage, double>::New();
  resample->SetInput(ct);
  resample->SetTransform(transform);
  resample->SetInterpolator(itk::LinearInterpolateImageFunction<CtImage, double>::New());
  resample->SetReferenceImage(ct);
  resample->UseReferenceImageOn();
  resample->SetDefaultPixelValue(-1000);
  resample->Update();
  return resample->GetOutput();
}

Model model_of(const Volume& v) {
  Model m;
  m.dims = v.dims;
  m.spacing = v.spacing;
  m.origin = v.origin;
  m.direction = v.direction;
  m.hu = v.hu;
  TissueThresholds t;
  m.tissue.resize(v.size());
  for (std::size_t i = 0; i < v.size(); ++i) m.tissue[i] = static_cast<std::uint8_t>(t.classify(v.hu[i]));
  return m;
}

}  // namespace

TEST(PullbackRecipe, ItkResamplingReproducesTheDeformedCt) {
  if (!fs::exists(kNifti)) GTEST_SKIP() << kNifti << " is absent (../shared/data)";
  io::InputOptions opt;
  opt.downsample = 2;
  const io::Input in = io::load_input(kNifti, opt);
  const Model m = model_of(in.lattice);
  // A smooth anterior bump of up to 1.5 lattice units (9 mm): fold-free, the inverse mapping
  // has work to do.
  std::vector<Vec3> pos(static_cast<std::size_t>(m.size()));
  for (Index i = 0; i < m.size(); ++i) {
    const Int3 c = m.coords(i);
    const float dx = float(c.x - m.dims.x / 2), dz = float(c.z - m.dims.z / 2), dy = float(c.y - m.dims.y / 4);
    pos[i] = Vec3{};  // displacements from rest
    pos[i].y -= 1.5f * std::exp(-(dx * dx + dy * dy + dz * dz) / 60.0f);
  }
  const fs::path dir = fs::temp_directory_path() / ("hpcm_pullback_recipe_" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const io::ExportFiles f = io::export_frame(in, m, pos, dir.string(), "final", true);
  ASSERT_TRUE(f.integrity.clean());
  CtImage::Pointer deformed = read<CtImage>(f.deformed);
  CtImage::Pointer input = read<CtImage>(kNifti);
  const std::size_t n = input->GetPixelContainer()->Size();
  double change = 0;
  for (std::size_t k = 0; k < n; ++k) {
    const double d = double(deformed->GetBufferPointer()[k]) - input->GetBufferPointer()[k];
    change += d * d;
  }
  change = std::sqrt(change / double(n));
  ASSERT_GT(change, 1.0) << "the deformation changed nothing: the check would be void";
  for (const std::string& field : {f.pullback_nifti, f.pullback_nrrd}) {
    CtImage::Pointer warped = warp_with_itk(kNifti, field);
    double err = 0;
    for (std::size_t k = 0; k < n; ++k) {
      const double d = double(warped->GetBufferPointer()[k]) - deformed->GetBufferPointer()[k];
      err += d * d;
    }
    err = std::sqrt(err / double(n)) / change;
    std::printf("%s: rms change %.2f HU; ITK resampling vs hpcm %.4f %% of it\n", fs::path(field).filename().c_str(),
                change, 100 * err);
    EXPECT_LT(err, 0.01) << field;
  }
  fs::remove_all(dir);
}
