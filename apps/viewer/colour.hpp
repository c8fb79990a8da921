#pragma once
// Vertex colours of the slice views: HU window (grey) or tissue class, with an optional
// overlay of speed or displacement |X - X0| through a colour map. GL-free.
#include <array>
#include <cstdint>
#include <vector>

#include "hpcm/model.hpp"
#include "view_geometry.hpp"

namespace hpcm::viewer {

enum class BaseColour { HuWindow = 0, Tissue = 1 };
enum class Overlay { None = 0, Speed = 1, Displacement = 2 };
const char* base_colour_name(BaseColour c);  ///< "hu", "tissue"
const char* overlay_name(Overlay o);         ///< "none", "speed", "displacement"

struct ColourSettings {
  BaseColour base = BaseColour::HuWindow;
  float level = 40.0f, width = 400.0f;  ///< HU window (soft tissue), width > 0
  Overlay overlay = Overlay::None;
  float overlay_max = 1.0f;      ///< value mapped to the top of the colour map (> 0)
  float overlay_opacity = 0.85f;  ///< [0, 1]
  bool overlay_air = false;      ///< also colour air elements (they move with the lattice)
  bool operator==(const ColourSettings&) const = default;
};

/// RGBA8 packed as 0xAABBGGRR (little-endian byte order R, G, B, A).
using Rgba = std::uint32_t;
inline Rgba rgba(int r, int g, int b, int a = 255) {
  return static_cast<Rgba>(r & 255) | (static_cast<Rgba>(g & 255) << 8) | (static_cast<Rgba>(b & 255) << 16) |
         (static_cast<Rgba>(a & 255) << 24);
}
inline int red(Rgba c) { return int(c & 255); }
inline int green(Rgba c) { return int((c >> 8) & 255); }
inline int blue(Rgba c) { return int((c >> 16) & 255); }

/// Grey level of `hu` in the window [level - width/2, level + width/2].
Rgba hu_grey(float hu, float level, float width);
/// Fixed colour of a tissue class (air dark, skin&fat yellow, muscle&organ red, bone ivory).
Rgba tissue_colour(int tissue);
/// Colour map for overlays, t in [0, 1] (dark blue -> cyan -> green -> yellow -> red).
Rgba overlay_map(float t);
/// Base colour blended with the overlay colour of value / max (opacity grows with the value,
/// so zero shows the plain base colour).
Rgba blend_overlay(Rgba base, float value, float max_value, float opacity);

/// Colours of every vertex of slice k from the displacements from rest `disp` (u = X - X0).
/// `prev` (displacements at the end of the previous frame) is used for the speed overlay; it
/// may be empty (speed 0).
void slice_colours(const Model& m, Plane p, int k, const std::vector<Vec3>& disp, const std::vector<Vec3>& prev,
                   const ColourSettings& s, std::vector<Rgba>& out);

/// Largest overlay value over slice k (for the automatic colour-map range).
float slice_overlay_max(const Model& m, Plane p, int k, const std::vector<Vec3>& disp, const std::vector<Vec3>& prev,
                        Overlay o, bool include_air);

}  // namespace hpcm::viewer
