#include "hpcm/model.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

namespace hpcm {

namespace {

/// The grid on which links are tabulated: pair-mean HU clamped to the material's control-point
/// range (the material is constant outside it), in steps of at least 1/16 HU and at most
/// 65,535 levels. Entry 0 is Model::kNoLink.
struct LinkGrid {
  float lo, hi;
  double step;
  int levels;
  explicit LinkGrid(const MaterialTable& mat) {
    lo = mat.points.front().hu;
    hi = mat.points.back().hu;
    step = std::max(1.0 / 16.0, (static_cast<double>(hi) - lo) / 65533.0);
    levels = static_cast<int>(std::floor((static_cast<double>(hi) - lo) / step)) + 2;  // + the level at hi
  }
  std::uint16_t key(float mean_hu) const {
    if (!(mean_hu > lo)) return 1;
    if (mean_hu >= hi) return static_cast<std::uint16_t>(levels);
    const long k = std::lround((static_cast<double>(mean_hu) - lo) / step);
    return static_cast<std::uint16_t>(1 + std::min<long>(k, levels - 1));
  }
  float hu(int key) const { return key == levels ? hi : static_cast<float>(lo + (key - 1) * step); }
};

}  // namespace

void rebuild_materials(Model& m, const Params& p) {
  const Index n = m.size();
  m.tissue.resize(static_cast<std::size_t>(n));
  m.tau.resize(static_cast<std::size_t>(n));
  for (auto& l : m.link_index) l.resize(static_cast<std::size_t>(n));
  std::array<Index, kTissueCount> counts{};
  const int nx = m.dims.x, ny = m.dims.y, nz = m.dims.z;
#pragma omp parallel for schedule(static)
  for (Index i = 0; i < n; ++i) {
    m.tissue[i] = static_cast<std::uint8_t>(p.tissue.classify(m.hu[i]));
    m.tau[i] = p.material.tau(m.hu[i]);
  }
  std::array<Index, kTissueCount> counted{};
  for (Index i = 0; i < n; ++i) {
    ++counts[m.tissue[i]];
    if (m.counted(i)) ++counted[m.tissue[i]];
  }
  m.class_count = counts;
  m.counted_class_count = counted;
  const LinkGrid grid(p.material);
  m.link_table.resize(static_cast<std::size_t>(grid.levels) + 1);
  m.link_tau.resize(m.link_table.size());
  m.link_tau[Model::kNoLink] = 0.0f;
  m.link_table[Model::kNoLink] = limits_from_tau(0.0f, 1.0f);  // {1, 1, 0, 1}: never read
#pragma omp parallel for schedule(static)
  for (int k = 1; k <= grid.levels; ++k) {
    const float hu = grid.hu(k);
    const float tau = p.material.tau(hu);
    m.link_tau[static_cast<std::size_t>(k)] = tau;
    m.link_table[static_cast<std::size_t>(k)] = limits_from_tau(tau, p.material.w(hu));
  }
  const Index stride[3] = {1, nx, static_cast<Index>(nx) * ny};
#pragma omp parallel for schedule(static)
  for (int z = 0; z < nz; ++z)
    for (int y = 0; y < ny; ++y)
      for (int x = 0; x < nx; ++x) {
        const Index i = m.index(x, y, z);
        const int c[3] = {x, y, z};
        const int d[3] = {nx, ny, nz};
        for (int a = 0; a < 3; ++a)
          m.link_index[a][i] = c[a] + 1 < d[a] ? grid.key(0.5f * (m.hu[i] + m.hu[i + stride[a]])) : Model::kNoLink;
      }
}

std::string BodySummary::describe() const {
  switch (search) {
    case Search::NotSearched:
      return "body: not searched (no image library for this input); statistics cover every element";
    case Search::NoBody:
      return "body: none found (" + method + "); statistics cover every element";
    case Search::Found:
      break;
  }
  return "body: " + std::to_string(body) + " elements (" + method + "); left out of the statistics: " +
         std::to_string(outside_air) + " outside air (HU < -500, free) and " + std::to_string(outside_objects) +
         " outside objects such as the table (HU >= -500, anchored)";
}

namespace {
Region region_of(bool in_body, float hu) {
  if (in_body) return Region::Body;
  return hu >= kBodyHu ? Region::OutsideObject : Region::OutsideAir;
}

// Region per element and the summary; `region` stays empty when there is no body.
BodySummary classify_body(const std::vector<float>& hu, const std::vector<std::uint8_t>& body_mask,
                          const std::string& method, std::vector<std::uint8_t>* region) {
  BodySummary s;
  s.body = static_cast<Index>(hu.size());
  if (region) region->clear();
  if (body_mask.empty()) return s;
  if (body_mask.size() != hu.size())
    throw Error("body mask has " + std::to_string(body_mask.size()) + " elements for a lattice of " +
                std::to_string(hu.size()));
  s.method = method;
  const Index inside = std::count_if(body_mask.begin(), body_mask.end(), [](std::uint8_t b) { return b != 0; });
  if (inside == 0) {
    s.search = BodySummary::Search::NoBody;  // a test object: everything counts
    return s;
  }
  s.search = BodySummary::Search::Found;
  s.body = inside;
  if (region) region->resize(body_mask.size());
  for (std::size_t i = 0; i < body_mask.size(); ++i) {
    const Region r = region_of(body_mask[i] != 0, hu[i]);
    if (region) (*region)[i] = static_cast<std::uint8_t>(r);
    if (r == Region::OutsideAir) ++s.outside_air;
    if (r == Region::OutsideObject) ++s.outside_objects;
  }
  return s;
}
}  // namespace

void set_body(Model& m, const std::vector<std::uint8_t>& body_mask, const std::string& method) {
  m.body = classify_body(m.hu, body_mask, method, &m.region);
}

BodySummary summarize_body(const Volume& v) { return classify_body(v.hu, v.body, v.body_method, nullptr); }

Model build_model(const Volume& v, const Params& p) {
  validate_volume(v, "volume");
  p.validate();
  const double n = static_cast<double>(v.dims.x) * v.dims.y * v.dims.z;
  if (n > static_cast<double>(std::numeric_limits<std::int32_t>::max()))
    throw Error("volume has " + std::to_string(static_cast<long long>(n)) +
                " elements; at most 2^31-1 are supported (use --downsample)");
  Model m;
  m.dims = v.dims;
  m.spacing = v.spacing;
  m.origin = v.origin;
  m.direction = v.direction;
  m.hu = v.hu;
  set_body(m, v.body, v.body_method);
  rebuild_materials(m, p);
  return m;
}

Index paper_grab_centre(const Model& m) {
  const int z = m.dims.z / 2, x = m.dims.x / 2;
  for (int y = 0; y < m.dims.y; ++y)
    if (m.hu[static_cast<std::size_t>(m.index(x, y, z))] >= kBodyHu) return m.index(x, y, z);
  throw Error("paper protocol: no element with HU >= -500 on the line x = " + std::to_string(x) +
              ", z = " + std::to_string(z) + " (is there a body in the volume?)");
}

double offset_length_mm(const Model& m, Vec3 offset) {
  double len2 = 0;
  for (int r = 0; r < 3; ++r) {
    double c = 0;
    for (int a = 0; a < 3; ++a) c += m.direction[r * 3 + a] * m.spacing[a] * offset[a];
    len2 += c * c;
  }
  return std::sqrt(len2);
}

Vec3 lattice_offset_of_mm(const Model& m, Vec3 offset_mm) {
  Vec3 out;
  for (int a = 0; a < 3; ++a) out[a] = static_cast<float>(offset_mm[a] / m.spacing[a]);
  return out;
}

int min_lattice_extent(float grab_radius) { return 2 * static_cast<int>(std::floor(grab_radius)) + 3; }

void check_lattice_extent(const Model& m, float grab_radius, const std::string& what) {
  const int need = min_lattice_extent(grab_radius);
  if (m.dims.x >= need && m.dims.y >= need && m.dims.z >= need) return;
  const int held = need - 2;
  std::ostringstream msg;
  msg << what << " (grab radius " << grab_radius << ") needs a lattice of at least " << need
      << " elements along every axis (the " << held << " the grab holds and a free one on each side), but the lattice is "
      << m.dims.x << "x" << m.dims.y << "x" << m.dims.z
      << "; use a smaller --downsample, a larger --roi or --phantom, or a smaller grab radius";
  throw Error(msg.str());
}

}  // namespace hpcm
