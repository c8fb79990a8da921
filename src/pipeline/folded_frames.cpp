#include "hpcm/folded_frames.hpp"

#include "pipeline/format_number.hpp"

namespace hpcm {

namespace {
// Beyond this many stretches the list ends with "...": the count and the extremes still say it all.
constexpr std::size_t kListedStretches = 8;
}  // namespace

void FoldedFrames::add(const FrameReport& r) {
  if (r.folded_cells <= 0) return;
  if (!ranges_.empty() && ranges_.back().second == r.frame - 1)
    ranges_.back().second = r.frame;
  else
    ranges_.push_back({r.frame, r.frame});
  ++frames_;
  if (r.folded_cells > max_cells_) max_cells_ = r.folded_cells;
  if (min_det_frame_ < 0 || r.min_cell_jacobian < min_det_) {
    min_det_ = r.min_cell_jacobian;
    min_det_frame_ = r.frame;
  }
}

std::string FoldedFrames::text() const {
  if (!any()) return {};
  std::string list;
  for (std::size_t k = 0; k < ranges_.size() && k < kListedStretches; ++k) {
    if (k > 0) list += ", ";
    const auto [a, b] = ranges_[k];
    list += a == b ? std::to_string(a) : std::to_string(a) + "-" + std::to_string(b);
  }
  if (ranges_.size() > kListedStretches) list += ", ...";
  const bool one = frames_ == 1;
  return std::to_string(frames_) + (one ? " frame folds (frame " : " frames fold (frames ") + list + "): " +
         (one ? "" : "up to ") + std::to_string(max_cells_) + (max_cells_ == 1 ? " cell" : " cells") +
         " with a corner determinant <= 0, smallest determinant " + detail::format_number(min_det_) + " (frame " +
         std::to_string(min_det_frame_) + ")";
}

}  // namespace hpcm
