// The synthetic phantom, model building (classes, links), rest state and link metrics.
#include <gtest/gtest.h>

#include "hpcm/model.hpp"
#include "hpcm/phantom.hpp"
#include "hpcm/state.hpp"

using namespace hpcm;

namespace {

TEST(Phantom, Deterministic) {
  PhantomOptions o;
  o.dims = {48, 40, 24};
  const Volume a = make_phantom(o), b = make_phantom(o);
  ASSERT_EQ(a.dims, o.dims);
  ASSERT_EQ(a.hu.size(), a.size());
  EXPECT_EQ(a.hu, b.hu);
  o.seed = 2;
  const Volume c = make_phantom(o);
  EXPECT_NE(a.hu, c.hu);  // the seed drives the noise
  o.noise_hu = 0;
  const Volume n0 = make_phantom(o);
  o.seed = 9;
  EXPECT_EQ(n0.hu, make_phantom(o).hu);  // without noise the seed does not matter
}

TEST(Phantom, FourNonEmptyClassesAndAnteriorAir) {
  PhantomOptions o;
  o.dims = {64, 64, 32};
  const Volume v = make_phantom(o);
  const Model m = build_model(v, Params{});
  for (int t = 0; t < kTissueCount; ++t) EXPECT_GT(m.class_count[t], 0) << tissue_name(t);
  Index total = 0;
  for (Index c : m.class_count) total += c;
  EXPECT_EQ(total, m.size());
  // Air in front of the body (anterior = -y), then the body surface on the paper's line.
  EXPECT_LT(v.at(32, 0, 16), -900.0f);
  const Index g = paper_grab_centre(m);
  const Int3 c = m.coords(g);
  EXPECT_EQ(c.x, 32);
  EXPECT_EQ(c.z, 16);
  EXPECT_GT(c.y, 0);
  EXPECT_GE(m.hu[g], -500.0f);
  EXPECT_LT(m.hu[m.index(32, c.y - 1, 16)], -500.0f);
  for (float h : v.hu) ASSERT_TRUE(std::isfinite(h));
}

// The variants change the anatomy where their names say, and nothing else about the options.
TEST(Phantom, VariantsChangeTheAnatomyTheyName) {
  PhantomOptions o;
  o.dims = {48, 48, 32};
  o.noise_hu = 0;
  const Volume standard = make_phantom(o);
  const Model ms = build_model(standard, Params{});
  const Int3 grab = ms.coords(paper_grab_centre(ms));
  for (PhantomVariant var : all_phantom_variants()) {
    EXPECT_EQ(parse_phantom_variant(phantom_variant_name(var), "variant"), var);
    if (var == PhantomVariant::Standard) continue;
    o.variant = var;
    const Volume v = make_phantom(o);
    EXPECT_NE(v.hu, standard.hu) << phantom_variant_name(var);
    EXPECT_EQ(v.hu, make_phantom(o).hu) << phantom_variant_name(var) << " is not deterministic";
  }
  auto line = [](const Volume& v, int y) { return v.at(v.dims.x / 2, y, v.dims.z / 2); };
  // Thin tissue: skin and fat are 2 elements, then bone right under the paper grab centre.
  o.variant = PhantomVariant::ThinTissue;
  const Volume thin = make_phantom(o);
  const Model mt = build_model(thin, Params{});
  const Int3 g = mt.coords(paper_grab_centre(mt));
  EXPECT_EQ(g, grab);
  EXPECT_LT(line(thin, g.y + 1), 25.0f);
  EXPECT_GE(line(thin, g.y + 2), 375.0f);
  EXPECT_GE(line(thin, g.y + 3), 375.0f);
  // Thick fat: the surface moves anterior and fat (below -50 HU) fills at least 7 elements.
  o.variant = PhantomVariant::ThickFat;
  const Volume fat = make_phantom(o);
  const Model mf = build_model(fat, Params{});
  const Int3 gf = mf.coords(paper_grab_centre(mf));
  EXPECT_LT(gf.y, grab.y - 3);
  for (int y = gf.y + 1; y <= gf.y + 7; ++y) EXPECT_LT(line(fat, y), -50.0f) << "y " << y;
  // Air pockets: gas right behind the anterior muscle wall under the grab.
  o.variant = PhantomVariant::AirPockets;
  const Volume gas = make_phantom(o);
  int gas_cells = 0;
  for (int y = grab.y; y < grab.y + 12; ++y) gas_cells += line(gas, y) < -900.0f;
  EXPECT_GE(gas_cells, 4);
  // Table: dense shells under the body, touching it (body tissue right above the top shell).
  o.variant = PhantomVariant::Table;
  const Volume table = make_phantom(o);
  int top = -1;  // first row, from the middle down, that is dense across the width and the length
  for (int y = table.dims.y / 2; y < table.dims.y && top < 0; ++y)
    if (line(table, y) >= 375.0f && table.at(4, y, 2) >= 375.0f) top = y;
  ASSERT_GT(top, 0) << "no table";
  EXPECT_GT(line(table, top - 1), -500.0f) << "the table does not touch the body";
  // Anisotropic: thick slices (0.8 : 0.8 : 5), same lattice.
  o.variant = PhantomVariant::Anisotropic;
  const Volume thick = make_phantom(o);
  EXPECT_EQ(thick.dims, o.dims);
  EXPECT_DOUBLE_EQ(thick.spacing[0], thick.spacing[1]);
  EXPECT_NEAR(thick.spacing[2] / thick.spacing[0], 6.25, 1e-12);
  EXPECT_THROW(parse_phantom_variant("thin", "--phantom-variant"), Error);
}

TEST(Phantom, RejectsBadOptions) {
  PhantomOptions o;
  o.dims = {7, 64, 64};
  EXPECT_THROW(make_phantom(o), Error);
  o.dims = {64, 64, 64};
  o.noise_hu = -1;
  EXPECT_THROW(make_phantom(o), Error);
}

TEST(Model, LinksFromPairMeanAndClasses) {
  Volume v;
  v.dims = {3, 2, 2};
  v.hu = {-1000, -100, 50, 700, 0, 10, 20, 30, 400, 500, -50, 1000};
  const Params p;
  const Model m = build_model(v, p);
  ASSERT_EQ(m.size(), 12);
  for (Index i = 0; i < m.size(); ++i) {
    EXPECT_EQ(m.tissue[i], static_cast<std::uint8_t>(p.tissue.classify(v.hu[i])));
    EXPECT_FLOAT_EQ(m.tau[i], p.material.tau(v.hu[i]));
  }
  const Index stride[3] = {1, 3, 6};
  for (Index i = 0; i < m.size(); ++i) {
    const Int3 c = m.coords(i);
    const int cc[3] = {c.x, c.y, c.z}, d[3] = {3, 2, 2};
    for (int a = 0; a < 3; ++a) {
      if (cc[a] + 1 >= d[a]) continue;
      // The model tabulates links at the pair's mean HU on a 1/16 HU grid: within 1e-4 of the
      // material's exact limits there.
      const LinkLimits want = p.material.link(v.hu[i], v.hu[i + stride[a]]);
      const LinkLimits got = m.link(a, i);
      EXPECT_NEAR(got.min_stretch, want.min_stretch, 1e-4f);
      EXPECT_NEAR(got.max_stretch, want.max_stretch, 1e-4f);
      EXPECT_NEAR(got.shear, want.shear, 1e-4f);
      EXPECT_NEAR(got.w, want.w, 1e-4f);
      EXPECT_NE(m.link_index[a][i], Model::kNoLink);
    }
  }
  // Half-open classes: -1000 is skin_fat with t1 = -1000 (air is HU < t1).
  EXPECT_EQ(m.class_count[0], 0);
  EXPECT_EQ(m.class_count[1], 6);
  EXPECT_EQ(m.class_count[2], 2);
  EXPECT_EQ(m.class_count[3], 4);
}

TEST(Model, RestStateAndLinkViolation) {
  Volume v;
  v.dims = {4, 2, 2};
  v.hu.assign(v.size(), 50.0f);
  const Model m = build_model(v, Params{});
  State s = State::rest(m);
  for (Index i = 0; i < m.size(); ++i) {
    EXPECT_EQ(s.disp[i], Vec3{});
    EXPECT_EQ(s.vel[i], Vec3{});
    EXPECT_TRUE(std::isinf(s.time[i]));
    EXPECT_EQ(s.flags[i], 0);
  }
  EXPECT_EQ(max_link_violation(m, s.disp), 0.0f);
  const float tau = m.link(0, 0).shear;
  s.disp[m.index(1, 1, 0)].y += tau + 0.25f;  // shear on its x and z links, stretch of its one y link
  EXPECT_NEAR(max_link_violation(m, s.disp), 0.25f, 1e-5f);
}

TEST(Model, Errors) {
  Volume v;
  v.dims = {0, 3, 3};
  EXPECT_THROW(build_model(v, Params{}), Error);
  v.dims = {3, 3, 3};
  v.hu.assign(27, 0.0f);
  Params p;
  p.dynamics.alpha = 3;
  EXPECT_THROW(build_model(v, p), Error);
  // No body on the paper's line.
  p = Params{};
  v.hu.assign(27, -1000.0f);
  EXPECT_THROW(paper_grab_centre(build_model(v, p)), Error);
}

}  // namespace

// SPEC §3, "The body, and what is not tissue": the phantom generator knows its own body.
namespace {

TEST(Body, PhantomKnowsItsBodyAndTheTableIsAnOutsideObject) {
  PhantomOptions o;
  o.dims = {48, 48, 32};
  o.variant = PhantomVariant::Table;
  const Volume v = make_phantom(o);
  ASSERT_EQ(v.body.size(), v.size());
  const Model m = build_model(v, Params{});
  ASSERT_EQ(m.body.search, BodySummary::Search::Found);
  ASSERT_EQ(m.region.size(), v.size());
  EXPECT_EQ(m.body.body + m.body.outside_air + m.body.outside_objects, m.size());
  // The table: every non-air element below its top (y >= 0.80 ny) is an outside object, and
  // every outside object is there (the air around the body has no element at -500 HU or more).
  const int table_top = static_cast<int>(0.80 * o.dims.y);
  Index table_dense = 0;
  for (Index i = 0; i < m.size(); ++i) {
    const Int3 c = m.coords(i);
    if (m.outside_object(i)) EXPECT_GE(c.y, table_top) << "outside object above the table at " << c.x << "," << c.y << "," << c.z;
    if (c.y >= table_top + 1 && m.hu[i] >= kBodyHu) {
      ++table_dense;
      EXPECT_TRUE(m.outside_object(i)) << "the table's shell at " << c.x << "," << c.y << "," << c.z << " is not outside";
    }
    if (m.counted(i)) EXPECT_LT(c.y, table_top + 1) << "body element inside the table";
  }
  EXPECT_GT(table_dense, Index{0});
  // The foam core (-850 HU, skin&fat by the class thresholds) is outside air: not counted.
  const int skin = static_cast<int>(Tissue::SkinFat);
  EXPECT_LT(m.counted_class_count[skin], m.class_count[skin]);
  Index counted = 0;
  for (int t = 0; t < kTissueCount; ++t) counted += m.counted_class_count[t];
  EXPECT_EQ(counted, m.body.body);
  EXPECT_NE(m.body.describe().find(std::to_string(m.body.outside_objects) + " outside objects"), std::string::npos);
}

TEST(Body, StandardPhantomHasNoOutsideObjects) {
  PhantomOptions o;
  o.dims = {48, 48, 32};
  const Model m = build_model(make_phantom(o), Params{});
  ASSERT_EQ(m.body.search, BodySummary::Search::Found);
  EXPECT_EQ(m.body.outside_objects, 0);
  EXPECT_GT(m.body.outside_air, m.size() / 10);  // the air around the elliptic body
  // The body's outline: the anterior border row is air, the centre is body.
  EXPECT_FALSE(m.counted(m.index(24, 0, 16)));
  EXPECT_TRUE(m.counted(m.index(24, 24, 16)));
}

TEST(Body, NoBodyOrNotSearchedCountsEveryElement) {
  Volume v;
  v.dims = {8, 8, 8};
  v.hu.assign(v.size(), -1000.0f);
  Model m = build_model(v, Params{});  // not searched
  EXPECT_EQ(m.body.search, BodySummary::Search::NotSearched);
  EXPECT_TRUE(m.region.empty());
  EXPECT_EQ(m.counted_class_count, m.class_count);
  EXPECT_NE(m.body.describe().find("not searched"), std::string::npos);
  v.body.assign(v.size(), 0);  // searched, nothing found: a test object
  v.body_method = "test";
  m = build_model(v, Params{});
  EXPECT_EQ(m.body.search, BodySummary::Search::NoBody);
  EXPECT_EQ(m.counted_class_count, m.class_count);
  EXPECT_TRUE(m.counted(0));
  EXPECT_NE(m.body.describe().find("none found"), std::string::npos);
  v.body.assign(5, 1);  // a mask of another grid
  EXPECT_THROW(build_model(v, Params{}), Error);
}

}  // namespace
