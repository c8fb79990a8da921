#pragma once
// Frames whose end positions fold (a cell corner determinant <= 0): what `hpcm run` and
// `hpcm experiment` warn about, and what their --strict refuses. The frame-end link
// restoration keeps every frame fold-free (docs/solver.md, "No fold"); this is the check
// that says so, or says where it did not hold.
#include <string>
#include <utility>
#include <vector>

#include "hpcm/simulation.hpp"

namespace hpcm {

class FoldedFrames {
 public:
  /// After each frame; frames without the measurement (folded_cells < 0) are ignored.
  void add(const FrameReport& r);
  bool any() const { return frames_ > 0; }
  int frames() const { return frames_; }               ///< frames that fold
  Index max_cells() const { return max_cells_; }        ///< most folded cells in one frame
  float min_det() const { return min_det_; }            ///< smallest determinant in those frames
  int min_det_frame() const { return min_det_frame_; }  ///< the frame it occurred in
  /// "3 frames fold (frames 4-5, 9): up to 6 cells with a corner determinant <= 0, smallest
  /// determinant -0.093 (frame 4)"; empty when no frame folds.
  std::string text() const;

 private:
  std::vector<std::pair<int, int>> ranges_;  ///< consecutive folded frames, first and last
  int frames_ = 0;
  Index max_cells_ = 0;
  float min_det_ = 0;
  int min_det_frame_ = -1;
};

}  // namespace hpcm
