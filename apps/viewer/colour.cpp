#include "colour.hpp"

#include <algorithm>
#include <cmath>

namespace hpcm::viewer {

const char* base_colour_name(BaseColour c) { return c == BaseColour::Tissue ? "tissue" : "hu"; }

const char* overlay_name(Overlay o) {
  switch (o) {
    case Overlay::None: return "none";
    case Overlay::Speed: return "speed";
    case Overlay::Displacement: return "displacement";
  }
  return "none";
}

Rgba hu_grey(float hu, float level, float width) {
  const float t = std::clamp((hu - (level - 0.5f * width)) / std::max(width, 1e-6f), 0.0f, 1.0f);
  const int g = static_cast<int>(std::lround(255.0f * t));
  return rgba(g, g, g);
}

Rgba tissue_colour(int tissue) {
  switch (tissue) {
    case 0: return rgba(18, 18, 28);      // air
    case 1: return rgba(226, 190, 120);   // skin & fat
    case 2: return rgba(178, 64, 58);     // muscle & organ
    case 3: return rgba(240, 236, 214);   // bone
    default: return rgba(255, 0, 255);
  }
}

Rgba overlay_map(float t) {
  if (!(t >= 0.0f)) t = 0.0f;  // NaN -> 0
  t = std::min(t, 1.0f);
  static const float stops[5][3] = {{20, 40, 160}, {0, 190, 230}, {40, 200, 60}, {250, 220, 30}, {230, 30, 20}};
  const float x = t * 4.0f;
  const int i = std::min(3, static_cast<int>(x));
  const float f = x - float(i);
  int c[3];
  for (int k = 0; k < 3; ++k) c[k] = static_cast<int>(std::lround(stops[i][k] + f * (stops[i + 1][k] - stops[i][k])));
  return rgba(c[0], c[1], c[2]);
}

Rgba blend_overlay(Rgba base, float value, float max_value, float opacity) {
  if (!(value > 0.0f) || !(max_value > 0.0f) || opacity <= 0.0f) return base;
  const float t = std::min(value / max_value, 1.0f);
  const float a = std::clamp(opacity, 0.0f, 1.0f) * std::sqrt(t);
  const Rgba o = overlay_map(t);
  auto mix = [a](int x, int y) { return static_cast<int>(std::lround(float(x) + a * float(y - x))); };
  return rgba(mix(red(base), red(o)), mix(green(base), green(o)), mix(blue(base), blue(o)));
}

namespace {
// From displacements, not positions: far from the lattice origin a position's float step
// (6e-5 at x = 512) would hide the slow motion the speed overlay is there to show.
float overlay_value(Index i, const std::vector<Vec3>& disp, const std::vector<Vec3>& prev, Overlay o) {
  const auto u = static_cast<std::size_t>(i);
  if (o == Overlay::Speed) return prev.size() == disp.size() ? norm(disp[u] - prev[u]) : 0.0f;
  if (o == Overlay::Displacement) return norm(disp[u]);
  return 0.0f;
}
}  // namespace

void slice_colours(const Model& m, Plane p, int k, const std::vector<Vec3>& disp, const std::vector<Vec3>& prev,
                   const ColourSettings& s, std::vector<Rgba>& out) {
  const auto [nu, nv] = slice_size(m, p);
  out.resize(static_cast<std::size_t>(nu) * nv);
  for (int b = 0; b < nv; ++b)
    for (int a = 0; a < nu; ++a) {
      const Index i = slice_element(m, p, k, a, b);
      const auto u = static_cast<std::size_t>(i);
      Rgba c = s.base == BaseColour::Tissue ? tissue_colour(m.tissue[u]) : hu_grey(m.hu[u], s.level, s.width);
      if (s.overlay != Overlay::None && (s.overlay_air || m.tissue[u] != 0))
        c = blend_overlay(c, overlay_value(i, disp, prev, s.overlay), s.overlay_max, s.overlay_opacity);
      out[static_cast<std::size_t>(a) + static_cast<std::size_t>(nu) * b] = c;
    }
}

float slice_overlay_max(const Model& m, Plane p, int k, const std::vector<Vec3>& disp, const std::vector<Vec3>& prev,
                        Overlay o, bool include_air) {
  if (o == Overlay::None) return 0.0f;
  const auto [nu, nv] = slice_size(m, p);
  float mx = 0.0f;
  for (int b = 0; b < nv; ++b)
    for (int a = 0; a < nu; ++a) {
      const Index i = slice_element(m, p, k, a, b);
      if (include_air || m.tissue[static_cast<std::size_t>(i)] != 0) mx = std::max(mx, overlay_value(i, disp, prev, o));
    }
  return mx;
}

}  // namespace hpcm::viewer
