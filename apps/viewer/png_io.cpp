#include "png_io.hpp"

#include <png.h>

#include <cstdio>
#include <cstring>
#include <filesystem>

#include "hpcm/types.hpp"

namespace hpcm::viewer {

void write_png(const Image& img, const std::string& path) {
  if (img.width <= 0 || img.height <= 0 ||
      img.rgb.size() != static_cast<std::size_t>(img.width) * static_cast<std::size_t>(img.height) * 3)
    throw Error("screenshot " + path + ": empty or inconsistent image (" + std::to_string(img.width) + "x" +
                std::to_string(img.height) + ")");
  const std::string tmp = path + ".tmp";
  png_image pi;
  std::memset(&pi, 0, sizeof pi);
  pi.version = PNG_IMAGE_VERSION;
  pi.width = static_cast<png_uint_32>(img.width);
  pi.height = static_cast<png_uint_32>(img.height);
  pi.format = PNG_FORMAT_RGB;
  if (!png_image_write_to_file(&pi, tmp.c_str(), 0, img.rgb.data(), img.width * 3, nullptr)) {
    const std::string why = pi.message;
    png_image_free(&pi);
    std::remove(tmp.c_str());
    throw Error("cannot write PNG " + path + ": " + why);
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    std::remove(tmp.c_str());
    throw Error("cannot write PNG " + path + ": " + ec.message());
  }
}

Image read_png(const std::string& path) {
  png_image pi;
  std::memset(&pi, 0, sizeof pi);
  pi.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&pi, path.c_str()))
    throw Error("cannot read PNG " + path + ": " + pi.message);
  pi.format = PNG_FORMAT_RGB;
  Image img;
  img.width = static_cast<int>(pi.width);
  img.height = static_cast<int>(pi.height);
  img.rgb.resize(PNG_IMAGE_SIZE(pi));
  if (!png_image_finish_read(&pi, nullptr, img.rgb.data(), 0, nullptr)) {
    const std::string why = pi.message;
    png_image_free(&pi);
    throw Error("cannot read PNG " + path + ": " + why);
  }
  return img;
}

}  // namespace hpcm::viewer
