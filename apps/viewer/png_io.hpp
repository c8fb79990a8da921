#pragma once
// PNG files for screenshots (libpng's simplified API). GL-free.
#include <cstdint>
#include <string>
#include <vector>

namespace hpcm::viewer {

/// 8-bit RGB image, rows top to bottom.
struct Image {
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgb;  ///< width * height * 3
};

/// Writes `img` as an 8-bit RGB PNG; atomic (temporary file + rename). Throws hpcm::Error
/// naming the path on failure.
void write_png(const Image& img, const std::string& path);
/// Reads any PNG as 8-bit RGB. Throws hpcm::Error naming the path on failure.
Image read_png(const std::string& path);

}  // namespace hpcm::viewer
