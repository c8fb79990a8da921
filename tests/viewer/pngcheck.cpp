// Small PNG checker for the headless viewer test (tests/viewer/viewer_headless.sh).
//   pngcheck size IMG W H                 exit 0 when IMG is W x H
//   pngcheck diff A B CX CY R             print the mean absolute difference (0..255 per
//                                         channel) of A and B in the square of half-size R
//                                         around pixel (CX, CY), clipped to the image
//   pngcheck ring IMG CX CY R             print the fraction of bright pixels (all channels
//                                         >= 170) on the circle of radius R around (CX, CY)
//   pngcheck count IMG CX CY R RR GG BB T  print how many pixels in the square of half-size R
//                                         around (CX, CY) have every channel within T of
//                                         (RR, GG, BB)
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "png_io.hpp"

using hpcm::viewer::Image;
using hpcm::viewer::read_png;

namespace {

int usage() {
  std::fprintf(stderr, "usage: pngcheck size IMG W H | diff A B CX CY R | ring IMG CX CY R | count IMG CX CY R RR GG BB T\n");
  return 2;
}

double mean_diff(const Image& a, const Image& b, double cx, double cy, double r) {
  const int x0 = std::max(0, int(std::floor(cx - r))), x1 = std::min(a.width, int(std::ceil(cx + r)));
  const int y0 = std::max(0, int(std::floor(cy - r))), y1 = std::min(a.height, int(std::ceil(cy + r)));
  double sum = 0;
  long n = 0;
  for (int y = y0; y < y1; ++y)
    for (int x = x0; x < x1; ++x)
      for (int c = 0; c < 3; ++c) {
        const std::size_t k = (static_cast<std::size_t>(y) * a.width + x) * 3 + c;
        sum += std::abs(int(a.rgb[k]) - int(b.rgb[k]));
        ++n;
      }
  return n > 0 ? sum / double(n) : 0.0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) return usage();
  const std::string cmd = argv[1];
  try {
    if (cmd == "size" && argc == 5) {
      const Image img = read_png(argv[2]);
      const int w = std::atoi(argv[3]), h = std::atoi(argv[4]);
      std::printf("%s: %dx%d\n", argv[2], img.width, img.height);
      return img.width == w && img.height == h ? 0 : 1;
    }
    if (cmd == "diff" && argc == 7) {
      const Image a = read_png(argv[2]), b = read_png(argv[3]);
      if (a.width != b.width || a.height != b.height) {
        std::fprintf(stderr, "pngcheck: sizes differ (%dx%d vs %dx%d)\n", a.width, a.height, b.width, b.height);
        return 1;
      }
      std::printf("%.4f\n", mean_diff(a, b, std::atof(argv[4]), std::atof(argv[5]), std::atof(argv[6])));
      return 0;
    }
    if (cmd == "ring" && argc == 6) {
      const Image img = read_png(argv[2]);
      const double cx = std::atof(argv[3]), cy = std::atof(argv[4]), r = std::atof(argv[5]);
      int bright = 0, n = 0;
      for (int k = 0; k < 72; ++k) {
        const double t = 2 * M_PI * k / 72;
        // Anti-aliased rings: look at the pixels within 1 px of the circle.
        bool hit = false, inside = false;
        for (double dr = -1.0; dr <= 1.0; dr += 0.5) {
          const int x = int(std::lround(cx + (r + dr) * std::cos(t))), y = int(std::lround(cy + (r + dr) * std::sin(t)));
          if (x < 0 || y < 0 || x >= img.width || y >= img.height) continue;
          inside = true;
          const std::uint8_t* p = &img.rgb[(static_cast<std::size_t>(y) * img.width + x) * 3];
          hit |= p[0] >= 170 && p[1] >= 170 && p[2] >= 170;
        }
        if (!inside) continue;
        ++n;
        bright += hit;
      }
      std::printf("%.4f\n", n > 0 ? double(bright) / n : 0.0);
      return 0;
    }
    if (cmd == "count" && argc == 10) {
      const Image img = read_png(argv[2]);
      const double cx = std::atof(argv[3]), cy = std::atof(argv[4]), r = std::atof(argv[5]);
      const int want[3] = {std::atoi(argv[6]), std::atoi(argv[7]), std::atoi(argv[8])}, tol = std::atoi(argv[9]);
      const int x0 = std::max(0, int(std::floor(cx - r))), x1 = std::min(img.width, int(std::ceil(cx + r)));
      const int y0 = std::max(0, int(std::floor(cy - r))), y1 = std::min(img.height, int(std::ceil(cy + r)));
      long n = 0;
      for (int y = y0; y < y1; ++y)
        for (int x = x0; x < x1; ++x) {
          const std::uint8_t* p = &img.rgb[(static_cast<std::size_t>(y) * img.width + x) * 3];
          bool near = true;
          for (int c = 0; c < 3; ++c) near &= std::abs(int(p[c]) - want[c]) <= tol;
          n += near;
        }
      std::printf("%ld\n", n);
      return 0;
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "pngcheck: %s\n", e.what());
    return 1;
  }
  return usage();
}
