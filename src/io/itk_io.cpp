// hpcm::io on ITK 5: reading NIfTI / NRRD / MetaImage files and DICOM series (GDCM, including
// JPEG-2000), writing volumes, displacement fields and label maps for 3D Slicer.
// All ITK code of the project is in this one translation unit (compile time).
#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <optional>
#include <set>
#include <sstream>
#include <fcntl.h>
#include <unistd.h>

#include <gdcmReader.h>
#include <gdcmStringFilter.h>
#include <itkGDCMImageIO.h>
#include <itkImage.h>
#include <itkImageFileReader.h>
#include <itkMetaDataObject.h>
#include <itkMetaImageIO.h>
#include <itkNiftiImageIO.h>
#include <itkNrrdImageIO.h>
#include <itkVector.h>
#include <itkVectorImage.h>
#include <zlib.h>

#include "hpcm/io.hpp"
#include "hpcm/tissue.hpp"
#include "input_checks.hpp"
#include "io_detail.hpp"

namespace fs = std::filesystem;

namespace hpcm::io {
namespace {

using detail::Format;
using FloatImage = itk::Image<float, 3>;

constexpr const char* kSupported = ".nii, .nii.gz, .nrrd, .nhdr, .mha, .mhd or a DICOM series directory";

// ITK exception text on one line, without ITK's file/line prefix.
std::string one_line(const itk::ExceptionObject& e) {
  std::string s = e.GetDescription();
  for (char& c : s)
    if (c == '\n' || c == '\r' || c == '\t') c = ' ';
  std::string out;
  for (char c : s)
    if (!(c == ' ' && !out.empty() && out.back() == ' ')) out += c;
  while (!out.empty() && out.back() == ' ') out.pop_back();
  if (out.size() > 240) out = out.substr(0, 237) + "...";
  return out;
}

std::string trim(std::string s) {
  const auto b = s.find_first_not_of(" \t\r\n");
  if (b == std::string::npos) return "";
  const auto e = s.find_last_not_of(" \t\r\n");
  return s.substr(b, e - b + 1);
}

itk::ImageIOBase::Pointer make_io(Format f) {
  switch (f) {
    case Format::Nifti:
    case Format::NiftiGz: return itk::NiftiImageIO::New().GetPointer();
    case Format::Nrrd:
    case Format::Nhdr: return itk::NrrdImageIO::New().GetPointer();
    case Format::Mha:
    case Format::Mhd: return itk::MetaImageIO::New().GetPointer();
    default: return nullptr;
  }
}

/// The grid of an ITK image as ITK gives it (file index order, LPS physical space).
template <class TImage>
Grid grid_of_image(const TImage* img) {
  Grid g;
  const auto size = img->GetLargestPossibleRegion().GetSize();
  g.dims = {int(size[0]), int(size[1]), int(size[2])};
  for (int a = 0; a < 3; ++a) {
    g.spacing[a] = img->GetSpacing()[a];
    g.origin[a] = img->GetOrigin()[a];
    for (int c = 0; c < 3; ++c) g.direction[a * 3 + c] = img->GetDirection()(a, c);
  }
  return g;
}

bool looks_like_dicom_file(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  char buf[132] = {};
  f.read(buf, sizeof buf);
  return f.gcount() == 132 && std::memcmp(buf + 128, "DICM", 4) == 0;
}

std::string dims_text(const std::vector<std::size_t>& d) {
  std::string s;
  for (std::size_t i = 0; i < d.size(); ++i) s += (i ? "x" : "") + std::to_string(d[i]);
  return s;
}

// Library output (GDCM, OpenJPEG, the NIfTI library, ITK's warnings) goes to stdout/stderr
// directly. While hpcm reads or writes, both file descriptors point into a temporary file; on
// failure that text becomes detail lines after hpcm's own one-line message, on success it is
// dropped (hpcm checks what those libraries warn about itself).
class LibraryOutputCapture {
 public:
  LibraryOutputCapture() {
    std::fflush(stdout);
    std::fflush(stderr);
    tmp_ = std::tmpfile();
    if (!tmp_) return;
    saved_out_ = ::dup(1);
    saved_err_ = ::dup(2);
    if (saved_out_ < 0 || saved_err_ < 0) {
      restore();
      return;
    }
    ::dup2(fileno(tmp_), 1);
    ::dup2(fileno(tmp_), 2);
  }
  ~LibraryOutputCapture() {
    restore();
    if (tmp_) std::fclose(tmp_);
  }
  LibraryOutputCapture(const LibraryOutputCapture&) = delete;
  LibraryOutputCapture& operator=(const LibraryOutputCapture&) = delete;

  void restore() {
    std::fflush(stdout);
    std::fflush(stderr);
    std::cout.flush();
    std::cerr.flush();
    if (saved_out_ >= 0) ::dup2(saved_out_, 1), ::close(saved_out_), saved_out_ = -1;
    if (saved_err_ >= 0) ::dup2(saved_err_, 2), ::close(saved_err_), saved_err_ = -1;
  }
  /// What the libraries printed, as indented lines (at most 8), "" when nothing.
  std::string detail() {
    restore();
    if (!tmp_) return "";
    std::rewind(tmp_);
    std::string text(4096, '\0');
    text.resize(std::fread(text.data(), 1, text.size(), tmp_));
    std::string out, line;
    int lines = 0;
    std::istringstream in(text);
    while (std::getline(in, line)) {
      line = trim(line);
      if (line.empty()) continue;
      if (++lines > 8) {
        out += "\n  | ...";
        break;
      }
      if (line.size() > 200) line = line.substr(0, 197) + "...";
      out += "\n  | " + line;
    }
    return out.empty() ? "" : "\n  library output while reading:" + out;
  }

 private:
  std::FILE* tmp_ = nullptr;
  int saved_out_ = -1, saved_err_ = -1;
};

// Refuses a volume of `voxels` that cannot be read into memory (file buffer + float copies).
void check_read_memory(const std::string& path, const std::vector<std::size_t>& d, double file_bytes_per_voxel) {
  const double n = double(d[0]) * double(d[1]) * double(d[2]);
  const double per_voxel = 2.0 * sizeof(float) + file_bytes_per_voxel + sizeof(float);  // ITK buffers + Volume
  const double need = n * per_voxel;
  const double avail = double(detail::available_memory_bytes());
  if (n > 2147483647.0 || need > avail)
    throw Error(path + ": volume " + dims_text({d[0], d[1], d[2]}) + " is too large: reading needs " +
                detail::format_bytes(need) + " (" + std::to_string(static_cast<unsigned long long>(need)) +
                " bytes) but " + detail::format_bytes(avail) + " of memory are available" +
                (n > 2147483647.0 ? " and at most 2^31-1 voxels are supported" : "") +
                "; crop it or down-sample it first");
}

// Checks the header of a scalar 3-D volume: components, dimensionality, memory.
Int3 check_header(const std::string& path, itk::ImageIOBase& io) {
  const unsigned nd = io.GetNumberOfDimensions();
  std::vector<std::size_t> d;
  for (unsigned a = 0; a < nd; ++a) d.push_back(io.GetDimensions(a));
  const unsigned nc = io.GetNumberOfComponents();
  if (nc != 1 || (io.GetPixelType() != itk::IOPixelEnum::SCALAR))
    throw Error(path + ": " + itk::ImageIOBase::GetPixelTypeAsString(io.GetPixelType()) + " image with " +
                std::to_string(nc) + " components per voxel; a scalar CT volume (1 component, HU) is needed");
  if (d.size() < 3 || (d.size() >= 3 && (d[0] < 2 || d[1] < 2 || d[2] < 2)))
    throw Error(path + ": a 2-D image (" + dims_text(d) + "); a 3-D volume with at least 2 voxels per axis is needed");
  for (std::size_t a = 3; a < d.size(); ++a)
    if (d[a] != 1)
      throw Error(path + ": a " + std::to_string(d.size()) + "-D image (" + dims_text(d) +
                  "); a single 3-D volume is needed");
  check_read_memory(path, d, double(io.GetComponentSize()));
  return {int(d[0]), int(d[1]), int(d[2])};
}

// HU plausibility. CT stores HU in 16 bits (about -1024..3071, up to ~30000 with metal on an
// extended scale; padding down to -32768): values beyond any 16-bit range are not HU at all.
constexpr float kHuMin = -32768.0f, kHuMax = 65535.0f;
constexpr float kHuWarnLow = -4096.0f, kHuWarnHigh = 32767.0f;

void check_hu(const std::string& path, const std::vector<float>& hu, std::vector<std::string>& warnings) {
  float lo = std::numeric_limits<float>::infinity(), hi = -lo;
  std::size_t outside = 0, far = 0;
  for (float h : hu) {
    lo = std::min(lo, h);
    hi = std::max(hi, h);
    far += (h < kHuMin || h > kHuMax);
    outside += (h < kHuWarnLow || h > kHuWarnHigh);
  }
  char buf[160];
  std::snprintf(buf, sizeof buf, "values %.6g..%.6g", lo, hi);
  if (far)
    throw Error(path + ": " + std::to_string(far) + " voxels lie outside [-32768, 65535] (" + buf +
                "); these are not Hounsfield units (a CT stores about -1024..3071, metal up to ~30000)");
  if (outside)
    warnings.push_back(path + ": " + std::to_string(outside) + " voxels lie outside [-4096, 32767] HU (" + buf +
                       "); they count as air (low) or bone (high): padding or a missing rescale?");
  else if (lo >= 0)
    warnings.push_back(path + ": no voxel below 0 HU (" + std::string(buf) +
                       "): air is about -1000 HU; if the rescale intercept is missing, every tissue class is wrong");
}

// Image (file index order, LPS geometry g) -> checked Volume in the same order (as stored).
Volume finish(const std::string& path, const float* data, const detail::Geometry& g, std::vector<std::string>& warnings) {
  for (int a = 0; a < 3; ++a) {
    if (!(g.spacing[a] > 0) || !std::isfinite(g.spacing[a]))
      throw Error(path + ": voxel spacing " + std::to_string(g.spacing[a]) + " along axis " + std::to_string(a) +
                  " is not a positive number");
    detail::check_spacing_value(path, "along axis " + std::to_string(a), g.spacing[a]);
  }
  for (double x : g.origin)
    if (!std::isfinite(x)) throw Error(path + ": the volume origin is not finite");
  for (int a = 0; a < 3; ++a)
    if (std::fabs(g.origin[a]) > detail::kMaxOriginMm) {
      char buf[160];
      std::snprintf(buf, sizeof buf, ": the volume origin's coordinate %d = %.6g mm is outside [-%.6g, %.6g] mm", a,
                    g.origin[a], detail::kMaxOriginMm, detail::kMaxOriginMm);
      throw Error(path + buf);
    }
  for (double x : g.direction)
    if (!std::isfinite(x)) throw Error(path + ": the direction matrix is not finite");
  const std::size_t n = std::size_t(g.dims.x) * g.dims.y * g.dims.z;
  std::size_t bad = 0, first = 0;
  for (std::size_t i = 0; i < n; ++i)
    if (!std::isfinite(data[i]) && bad++ == 0) first = i;
  if (bad) {
    const std::size_t x = first % g.dims.x, y = (first / g.dims.x) % g.dims.y, z = first / (std::size_t(g.dims.x) * g.dims.y);
    throw Error(path + ": " + std::to_string(bad) + " non-finite values (NaN or Inf), the first at voxel (" +
                std::to_string(x) + "," + std::to_string(y) + "," + std::to_string(z) + "); HU values must be finite");
  }
  Volume v;  // as stored: the file's index order and geometry (to_lps_order reorients)
  v.dims = g.dims;
  v.spacing = g.spacing;
  v.origin = g.origin;
  v.direction = g.direction;
  v.hu.assign(data, data + n);
  validate_volume(v, path);
  check_hu(path, v.hu, warnings);
  return v;
}

Volume finish(const std::string& path, FloatImage* img, std::vector<std::string>& warnings) {
  return finish(path, img->GetBufferPointer(), grid_of_image(img), warnings);
}

// The text header of a MetaImage or NRRD file (at most 1 MiB; binary data may follow).
std::string read_text_header(const std::string& path, bool nrrd) {
  std::ifstream in(path, std::ios::binary);
  std::string text(1 << 20, '\0');
  in.read(text.data(), std::streamsize(text.size()));
  text.resize(std::size_t(in.gcount()));
  // Cut at the end of the header so binary data never reaches the text parsers.
  std::size_t end = std::string::npos;
  if (nrrd) {
    end = text.find("\n\n");
    if (end == std::string::npos) end = text.find("\r\n\r\n");
  } else {
    const auto k = text.find("ElementDataFile");
    if (k != std::string::npos) end = text.find('\n', k);
  }
  return end == std::string::npos ? text : text.substr(0, end + 1);
}

// Bytes per stored NIfTI element, from the datatype code (bitpix when the code is unknown).
double nifti_element_bytes(const detail::NiftiHeader& h) {
  switch (h.datatype) {
    case 2: case 256: return 1;              // uint8, int8
    case 4: case 512: return 2;              // int16, uint16
    case 8: case 16: case 768: return 4;     // int32, float32, uint32
    case 64: case 1024: case 1280: return 8; // float64, int64, uint64
    default: return double(h.bitpix) / 8.0;
  }
}

// A compressed MetaImage data part: ITK trusts CompressedDataSize and leaves the rest of its
// buffer uninitialised when the stream is shorter than DimSize x ElementType. hpcm inflates the
// stream itself (output discarded) and needs the announced size to be the bytes present and
// the stream to end exactly at the voxel data's size.
void check_metaimage_stream(const std::string& path, const std::string& data_path, std::streamoff offset, double have,
                            double announced, double need) {
  const std::string pre = path + ": MetaImage compressed data";
  if (announced >= 0 && announced != have)
    throw Error(pre + ": CompressedDataSize = " + std::to_string(static_cast<long long>(announced)) + " but the " +
                (data_path == path ? "file holds " : "data file holds ") + std::to_string(static_cast<long long>(have)) +
                " bytes of data; the header lies (truncated or corrupt file)");
  std::ifstream in(data_path, std::ios::binary);
  in.seekg(offset);
  z_stream z{};
  if (inflateInit2(&z, 15 + 32) != Z_OK) throw Error(pre + ": cannot start zlib");  // zlib or gzip header
  std::vector<unsigned char> src(1 << 16), dst(1 << 16);
  double out = 0;
  int rc = Z_OK;
  while (rc != Z_STREAM_END) {
    in.read(reinterpret_cast<char*>(src.data()), std::streamsize(src.size()));
    z.next_in = src.data();
    z.avail_in = unsigned(in.gcount());
    if (z.avail_in == 0) break;
    do {
      z.next_out = dst.data();
      z.avail_out = unsigned(dst.size());
      rc = inflate(&z, Z_NO_FLUSH);
      out += double(dst.size() - z.avail_out);
    } while (rc == Z_OK && z.avail_out == 0);
    if (rc != Z_OK && rc != Z_STREAM_END && rc != Z_BUF_ERROR) break;
    if (out > need) break;  // more than the voxels: no need to inflate the rest
  }
  const std::string zmsg = z.msg ? z.msg : "";
  inflateEnd(&z);
  if (rc != Z_OK && rc != Z_STREAM_END && rc != Z_BUF_ERROR)
    throw Error(pre + " is corrupt (zlib: " + (zmsg.empty() ? std::to_string(rc) : zmsg) + ")");
  if (rc != Z_STREAM_END && out <= need)
    throw Error(pre + ": the compressed stream ends early, after " + std::to_string(static_cast<long long>(out)) +
                " of " + std::to_string(static_cast<long long>(need)) + " bytes (truncated file)");
  if (out != need)
    throw Error(pre + " inflates to " + (out > need ? "more than " : "") + std::to_string(static_cast<long long>(out)) +
                " bytes where DimSize x ElementType need " + std::to_string(static_cast<long long>(need)));
}

// A complete data part (NIfTI, MetaImage) and, for NIfTI, a checked header and finite float
// voxels: what ITK and the NIfTI library would not report or would repair silently (NaN -> 0).
void check_file_before_itk(const std::string& path, Format f, itk::ImageIOBase& io, const detail::NiftiHeader* nifti) {
  // NIfTI: the stored bytes from the header (ITK reports the size of the scaled float image
  // when scl_slope is set, twice the int16 data).
  double data_bytes = double(io.GetImageSizeInBytes());
  if (nifti) {
    data_bytes = nifti_element_bytes(*nifti);
    for (int i = 1; i <= nifti->dim[0]; ++i) data_bytes *= double(nifti->dim[std::size_t(i)]);
  }
  const std::string name = detail::format_name(f);
  auto truncated = [&](double have, double need) {
    throw Error(path + ": truncated or corrupt " + name + " file: " + std::to_string(static_cast<long long>(have)) +
                " bytes where the header announces " + std::to_string(static_cast<long long>(need)));
  };
  if (f == Format::Nifti || f == Format::NiftiGz) {
    gzFile gz = gzopen(path.c_str(), "rb");  // also reads uncompressed files
    if (!gz) throw Error(path + ": cannot open");
    std::vector<unsigned char> buf(1 << 16);
    std::vector<unsigned char> head;
    long long total = 0;
    double vox_offset = -1;
    std::optional<detail::NonFiniteScan> scan;
    for (;;) {
      const int n = gzread(gz, buf.data(), unsigned(buf.size()));
      if (n <= 0) break;
      const unsigned char* p = buf.data();
      std::size_t len = std::size_t(n);
      if (vox_offset < 0) {  // still collecting the header
        head.insert(head.end(), p, p + len);
        const std::size_t hsize = detail::nifti_header_size(head.data(), head.size());
        if (hsize && head.size() >= hsize) {
          const detail::NiftiHeader h = detail::check_nifti_header(path, head.data(), head.size());
          vox_offset = h.vox_offset;
          const bool is_float = h.datatype == 16 || h.datatype == 64;  // FLOAT32, FLOAT64
          if (is_float) scan.emplace(h.datatype == 16 ? 4 : 8, h.swapped);
          // Feed the data part of what was collected so far.
          if (scan && double(head.size()) > vox_offset)
            scan->feed(head.data() + std::size_t(vox_offset), head.size() - std::size_t(vox_offset));
        }
      } else if (scan) {
        const long long skip = std::max(0LL, static_cast<long long>(vox_offset) - total);
        if (skip < n) scan->feed(p + skip, len - std::size_t(skip));
      }
      total += n;
    }
    int err = Z_OK;
    const char* msg = gzerror(gz, &err);
    const std::string zmsg = (err != Z_OK && err != Z_STREAM_END && msg) ? msg : "";
    gzclose(gz);
    if (!zmsg.empty()) throw Error(path + ": truncated or corrupt " + name + " file (" + zmsg + ")");
    if (vox_offset >= 0 && double(total) < vox_offset + data_bytes) truncated(double(total), vox_offset + data_bytes);
    if (scan && scan->count() > 0)
      throw Error(path + ": " + std::to_string(scan->count()) + " non-finite values (NaN or Inf) in the voxel data, the first at element " +
                  std::to_string(scan->first_index()) + " (file order); HU values must be finite");
    return;
  }
  if (f == Format::Mha || f == Format::Mhd) {
    std::ifstream in(path, std::ios::binary);
    std::string line, data_file, field;
    bool compressed = false;
    double compressed_size = -1;
    while (std::getline(in, line)) {
      const auto eq = line.find('=');
      if (eq == std::string::npos) continue;
      const std::string key = trim(line.substr(0, eq)), value = trim(line.substr(eq + 1));
      if (key == "CompressedData") compressed = value == "True" || value == "true";
      if (key == "CompressedDataSize") compressed_size = std::atof(value.c_str());
      if (key == "ElementDataFile") {
        data_file = value;
        field = key;
        break;
      }
    }
    std::string data_path = path;
    std::streamoff offset = 0;
    if (data_file == "LOCAL" || data_file == "Local" || data_file == "local") {
      offset = in.tellg();
      if (offset < 0) throw Error(path + ": cannot find the data after the MetaImage header");
    } else {
      if (data_file.empty()) throw Error(path + ": MetaImage header without ElementDataFile");
      data_path = detail::resolve_data_file(path, field, data_file);
    }
    const double have = double(fs::file_size(data_path)) - double(offset);
    if (compressed)
      check_metaimage_stream(path, data_path, offset, have, compressed_size, data_bytes);
    else if (have < data_bytes)
      truncated(have, data_bytes);
  }
}

// The checked NIfTI header (before ITK sees the file: ITK spins on a 3e38 sform).
detail::NiftiHeader read_nifti_header(const std::string& path) {
  unsigned char head[540] = {};
  gzFile gz = gzopen(path.c_str(), "rb");
  if (!gz) throw Error(path + ": cannot open");
  const int n = gzread(gz, head, sizeof head);
  gzclose(gz);
  return detail::check_nifti_header(path, head, n > 0 ? std::size_t(n) : 0);
}

Volume read_file(const std::string& path, std::vector<std::string>& warnings) {
  const Format f = detail::format_of(path);
  if (f == Format::Unknown) {
    if (looks_like_dicom_file(path))
      throw Error(path + ": a single DICOM file; give the directory that holds the series instead");
    throw Error(path + ": unknown volume format (supported: " + kSupported + ")");
  }
  itk::ImageIOBase::Pointer io = make_io(f);
  const std::string name = detail::format_name(f);
  if (fs::file_size(path) == 0) throw Error(path + ": empty file, not a " + name + " volume");
  // hpcm's header checks run before ITK sees the file: ITK would take some of these values
  // (a negative spacing becomes positive, zero or NaN pixdim 1 mm), stop on others with a less
  // precise message, or abort the process (a NaN NIfTI sform).
  if (f == Format::Nrrd || f == Format::Nhdr) {
    const std::string text = read_text_header(path, true);
    detail::check_nrrd_header(path, text);
    std::string field;
    const std::string data_file = detail::nrrd_data_file(text, &field);
    if (!field.empty()) detail::resolve_data_file(path, field, data_file);
  }
  if (f == Format::Mha || f == Format::Mhd) {
    const std::string text = read_text_header(path, false);
    detail::check_metaimage_header(path, text);
    std::string field;
    const std::string data_file = detail::metaimage_data_file(text, &field);
    if (!data_file.empty() && data_file != "LOCAL" && data_file != "Local" && data_file != "local")
      detail::resolve_data_file(path, field, data_file);  // before ITK opens it
  }
  std::optional<detail::NiftiHeader> nifti;
  std::optional<detail::Geometry> nifti_grid;  // nibabel's affine; a sheared one is refused here
  if (f == Format::Nifti || f == Format::NiftiGz) {
    nifti = read_nifti_header(path);
    nifti_grid = detail::nifti_geometry(path, *nifti);
  }
  if (!io->CanReadFile(path.c_str()))
    throw Error(path + ": not a readable " + name + " file (corrupt or truncated header)");
  try {
    io->SetFileName(path);
    io->ReadImageInformation();
  } catch (const itk::ExceptionObject& e) {
    throw Error(path + ": corrupt " + name + " header: " + one_line(e));
  }
  check_header(path, *io);
  check_file_before_itk(path, f, *io, nifti ? &*nifti : nullptr);
  auto reader = itk::ImageFileReader<FloatImage>::New();
  reader->SetImageIO(io);
  reader->SetFileName(path);
  try {
    reader->Update();
  } catch (const itk::ExceptionObject& e) {
    throw Error(path + ": truncated or corrupt " + name + " file: " + one_line(e));
  }
  if (!nifti) return finish(path, reader->GetOutput(), warnings);
  // NIfTI: the grid from the affine nibabel uses (ITK chooses between qform and sform by its
  // own rules), and a note when the other one disagrees.
  const std::string source = detail::nifti_geometry_source(*nifti);
  if (source.find("differs") != std::string::npos) {
    const double mm = detail::nifti_affine_distance(*nifti, detail::nifti_affine(*nifti, detail::NiftiAffine::Sform),
                                                    detail::nifti_affine(*nifti, detail::NiftiAffine::Qform));
    char buf[48];
    std::snprintf(buf, sizeof buf, "%.6g", mm);
    warnings.push_back(path + ": the sform (sform_code " + std::to_string(nifti->sform_code) + ") and the qform (qform_code " +
                       std::to_string(nifti->qform_code) + ") differ (a corner voxel " + buf +
                       " mm apart); hpcm uses the sform, as nibabel does");
  }
  return finish(path, reader->GetOutput()->GetBufferPointer(), *nifti_grid, warnings);
}

// ---- DICOM series ----------------------------------------------------------------------------

const gdcm::Tag kSopClass(0x0008, 0x0016), kModality(0x0008, 0x0060), kSeriesDescription(0x0008, 0x103e),
    kSeriesUid(0x0020, 0x000e), kInstanceNumber(0x0020, 0x0013), kPosition(0x0020, 0x0032),
    kOrientation(0x0020, 0x0037), kFrames(0x0028, 0x0008), kRows(0x0028, 0x0010), kColumns(0x0028, 0x0011),
    kPixelSpacing(0x0028, 0x0030), kRescaleIntercept(0x0028, 0x1052), kRescaleSlope(0x0028, 0x1053);

// One file of a DICOM directory as read from its tags.
struct DicomFile {
  std::string name;       // file name inside the directory
  bool readable = false;  // a DICOM file GDCM could parse
  bool image = false;     // has an image matrix (Rows, Columns)
  std::string series, modality, description;
  detail::DicomSlice slice;
};

DicomFile read_dicom_tags(const fs::path& path) {
  DicomFile f;
  f.name = path.filename().string();
  f.slice.file = f.name;
  gdcm::Reader reader;
  reader.SetFileName(path.c_str());
  const std::set<gdcm::Tag> tags = {kSopClass,    kModality, kSeriesDescription, kSeriesUid,    kInstanceNumber,
                                    kPosition,    kOrientation, kFrames,         kRows,         kColumns,
                                    kPixelSpacing, kRescaleIntercept, kRescaleSlope};
  try {
    if (!reader.ReadSelectedTags(tags)) return f;
  } catch (...) {
    return f;  // GDCM throws on some malformed files: unreadable either way
  }
  const gdcm::DataSet& ds = reader.GetFile().GetDataSet();
  const gdcm::FileMetaInformation& meta = reader.GetFile().GetHeader();
  if (!ds.FindDataElement(kSopClass) && !meta.FindDataElement(gdcm::Tag(0x0002, 0x0002))) return f;
  f.readable = true;
  gdcm::StringFilter sf;
  sf.SetFile(reader.GetFile());
  const auto get = [&](const gdcm::Tag& t) { return ds.FindDataElement(t) ? trim(sf.ToString(t)) : std::string(); };
  f.series = get(kSeriesUid);
  f.modality = get(kModality);
  f.description = get(kSeriesDescription);
  detail::DicomSlice& s = f.slice;
  s.rows = std::atoi(get(kRows).c_str());
  s.columns = std::atoi(get(kColumns).c_str());
  f.image = s.rows > 0 && s.columns > 0;
  const std::string frames = get(kFrames);
  s.frames = frames.empty() ? 1 : std::max(0, std::atoi(frames.c_str()));
  s.instance = std::atoll(get(kInstanceNumber).c_str());
  s.position_text = get(kPosition);
  s.orientation_text = get(kOrientation);
  s.spacing_text = get(kPixelSpacing);
  s.intercept_text = get(kRescaleIntercept);
  s.slope_text = get(kRescaleSlope);
  s.has_position = detail::parse_ds(s.position_text, s.position.data(), 3);
  s.has_orientation = detail::parse_ds(s.orientation_text, s.orientation.data(), 6);
  s.has_spacing = detail::parse_ds(s.spacing_text, s.pixel_spacing.data(), 2);
  return f;
}

struct DicomDirectory {
  std::vector<DicomSeriesInfo> info;
  std::vector<std::vector<detail::DicomSlice>> slices;  // per series
  std::vector<std::string> unreadable;                  // files that are not readable DICOM
  std::size_t entries = 0;
};

// Reads the tags of every regular file of `dir` (not recursive; hidden files are skipped).
DicomDirectory scan_dicom_dir(const std::string& dir) {
  std::error_code ec;
  std::vector<fs::path> files;
  DicomDirectory out;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    ++out.entries;
    const std::string name = e.path().filename().string();
    std::error_code fec;
    if (name.empty() || name[0] == '.' || !e.is_regular_file(fec)) continue;
    files.push_back(e.path());
  }
  if (ec) throw Error(dir + ": cannot list the directory: " + ec.message());
  if (out.entries == 0) throw Error(dir + ": empty directory; expected the files of a DICOM series");
  std::sort(files.begin(), files.end());
  for (const fs::path& p : files) {
    DicomFile f = read_dicom_tags(p);
    if (!f.readable) {
      out.unreadable.push_back(f.name);
      continue;
    }
    if (!f.image) continue;  // DICOMDIR, structured reports, ...: not part of an image series
    std::size_t k = 0;
    while (k < out.info.size() && out.info[k].uid != f.series) ++k;
    if (k == out.info.size()) {
      DicomSeriesInfo s;
      s.uid = f.series;
      s.modality = f.modality;
      s.description = f.description;
      s.columns = f.slice.columns;
      s.rows = f.slice.rows;
      out.info.push_back(s);
      out.slices.emplace_back();
    }
    ++out.info[k].files;
    out.slices[k].push_back(f.slice);
  }
  if (out.info.empty())
    throw Error(dir + ": no DICOM image files among its " + std::to_string(out.entries) + " entries");
  return out;
}

// --series: a SeriesInstanceUID, or '#N' for the N-th series as listed (1-based).
std::optional<std::size_t> find_series(const std::vector<DicomSeriesInfo>& info, const std::string& wanted) {
  if (wanted.size() > 1 && wanted[0] == '#' && wanted.find_first_not_of("0123456789", 1) == std::string::npos &&
      wanted.size() < 10) {
    const std::size_t n = std::stoul(wanted.substr(1));
    if (n >= 1 && n <= info.size()) return n - 1;
    return std::nullopt;
  }
  for (std::size_t i = 0; i < info.size(); ++i)
    if (info[i].uid == wanted) return i;
  return std::nullopt;
}

// "#2 UID (CT, 20 slices 512x512, 'description')": the number is what --series '#2' takes
// (the only way to choose a series whose SeriesInstanceUID is empty).
std::string series_line(const DicomSeriesInfo& s, std::size_t index) {
  std::string t = "#" + std::to_string(index + 1) + " " + (s.uid.empty() ? std::string("<empty SeriesInstanceUID>") : s.uid) +
                  " (" + (s.modality.empty() ? "?" : s.modality) + ", " + std::to_string(s.files) + " slices " +
                  std::to_string(s.columns) + "x" + std::to_string(s.rows);
  if (!s.description.empty()) t += ", '" + s.description + "'";
  return t + ")";
}

std::string series_list(const std::vector<DicomSeriesInfo>& info, const std::vector<std::size_t>& which) {
  std::string list;
  for (std::size_t i : which) list += (list.empty() ? "" : "; ") + series_line(info[i], i);
  return list;
}

// The series --series names (a SeriesInstanceUID or '#N', N as listed), else the only CT series.
std::size_t choose_series(const std::string& dir, const std::vector<DicomSeriesInfo>& info, const std::string& wanted) {
  std::vector<std::size_t> all, ct;
  for (std::size_t i = 0; i < info.size(); ++i) {
    all.push_back(i);
    if (info[i].modality == "CT") ct.push_back(i);
  }
  if (wanted.empty()) {
    if (ct.empty()) throw Error(dir + ": no CT series in this DICOM directory (found: " + series_list(info, all) + ")");
    if (ct.size() > 1)
      throw Error(dir + ": " + std::to_string(ct.size()) + " CT series; choose one with --series UID or --series '#N' (N as listed): " +
                  series_list(info, ct));
    return ct.front();
  }
  const std::optional<std::size_t> pick = find_series(info, wanted);
  if (!pick) throw Error(dir + ": no series with --series " + wanted + " (the directory has: " + series_list(info, all) + ")");
  if (info[*pick].modality != "CT")
    throw Error(dir + ": series " + wanted + " is " +
                (info[*pick].modality.empty() ? std::string("of unknown modality") : info[*pick].modality) +
                ", not CT; HU values need a CT series");
  return *pick;
}

std::string list_names(const std::vector<std::string>& names) {
  std::string out;
  for (std::size_t i = 0; i < names.size() && i < 4; ++i) out += (i ? ", " : "") + names[i];
  if (names.size() > 4) out += " and " + std::to_string(names.size() - 4) + " more";
  return out;
}

Volume read_dicom_dir(const std::string& dir, const ReadOptions& opt, std::vector<std::string>& warnings) {
  DicomDirectory dd = scan_dicom_dir(dir);
  if (!dd.unreadable.empty()) {
    const std::string what = std::to_string(dd.unreadable.size()) + (dd.unreadable.size() == 1 ? " file is" : " files are") +
                             " not readable DICOM: " + list_names(dd.unreadable);
    if (!opt.dicom_skip_unreadable)
      throw Error(dir + ": " + what + "; remove " + (dd.unreadable.size() == 1 ? "it" : "them") +
                  ", or pass --dicom-skip-unreadable to ignore such files");
    warnings.push_back(dir + ": skipped (--dicom-skip-unreadable): " + what);
  }
  const std::size_t pick = choose_series(dir, dd.info, opt.series_uid);
  // Geometry from the tags of every slice, checked by hpcm (not ITK's average spacing).
  const detail::DicomStack stack =
      detail::plan_dicom_stack(dir, dd.slices[pick], opt.dicom_duplicates == DicomDuplicates::First);
  if (!stack.dropped_duplicates.empty())
    warnings.push_back(dir + ": --dicom-duplicates first: left out " + std::to_string(stack.dropped_duplicates.size()) +
                       " slice(s) at an already used position: " + list_names(stack.dropped_duplicates));
  const detail::Geometry& g = stack.geometry;
  check_read_memory(dir, {std::size_t(g.dims.x), std::size_t(g.dims.y), std::size_t(g.dims.z)}, 4.0);
  // Pixels slice by slice (GDCM applies each slice's RescaleSlope/Intercept: values are HU), so
  // an error names the file.
  const std::size_t slice_voxels = std::size_t(g.dims.x) * std::size_t(g.dims.y);
  std::vector<float> data(slice_voxels * std::size_t(g.dims.z));
  for (std::size_t k = 0; k < stack.files.size(); ++k) {
    const std::string file = (fs::path(dir) / stack.files[k]).string();
    auto dio = itk::GDCMImageIO::New();
    dio->SetGlobalWarningDisplay(false);
    auto reader = itk::ImageFileReader<FloatImage>::New();
    reader->SetImageIO(dio);
    reader->SetFileName(file);
    try {
      reader->Update();
    } catch (const itk::ExceptionObject& e) {
      throw Error(dir + ": cannot read the pixels of " + stack.files[k] + ": " + one_line(e));
    }
    const auto size = reader->GetOutput()->GetLargestPossibleRegion().GetSize();
    if (int(size[0]) != g.dims.x || int(size[1]) != g.dims.y || size[2] != 1)
      throw Error(dir + ": " + stack.files[k] + " holds a " + std::to_string(size[0]) + "x" + std::to_string(size[1]) + "x" +
                  std::to_string(size[2]) + " image where its tags say " + std::to_string(g.dims.x) + "x" +
                  std::to_string(g.dims.y));
    std::copy_n(reader->GetOutput()->GetBufferPointer(), slice_voxels, data.begin() + std::ptrdiff_t(k * slice_voxels));
  }
  return finish(dir, data.data(), g, warnings);
}

// ---- writing -------------------------------------------------------------------------------

// Writes into a fresh temporary folder beside the target, then renames the file(s) into place:
// a reader never sees a half-written file. For detached formats (.nhdr, .mhd) the data file
// is moved first and the header last.
// True when the header file `header` (.nhdr/.mhd text) names `data_name` as its data file.
bool header_names_data_file(const fs::path& header, const std::string& data_name) {
  std::ifstream in(header, std::ios::binary);
  std::string line;
  for (int i = 0; i < 200 && std::getline(in, line); ++i) {
    const auto k = line.find(line.rfind("data file", 0) == 0 ? ':' : '=');
    if ((line.rfind("data file", 0) == 0 || line.rfind("ElementDataFile", 0) == 0) && k != std::string::npos)
      return fs::path(trim(line.substr(k + 1))).filename() == data_name;
  }
  return false;
}

// A detached data file `data` may be (over)written for header `target` only when it does not
// exist yet or when `target` already exists and names it: two headers never share one data
// file (a.nhdr and a.mhd would both write a.raw), and no unrelated file is overwritten.
void check_data_file_free(const fs::path& target, const fs::path& data) {
  std::error_code ec;
  if (!fs::exists(fs::symlink_status(data, ec))) return;
  const std::string name = data.filename().string();
  if (fs::exists(target, ec) && header_names_data_file(target, name)) return;
  std::string owner;
  for (const char* ext : {".nhdr", ".mhd"}) {
    fs::path h = data;
    h.replace_filename(target.stem().string() + ext);
    if (h != target && fs::exists(h, ec) && header_names_data_file(h, name)) owner = h.filename().string();
  }
  throw Error(target.string() + ": its data file " + name + " already exists" +
              (owner.empty() ? std::string(" and is not this header's") : " and belongs to " + owner) +
              "; writing would silently change that volume: choose another name or remove " + name);
}

// The data file ITK writes beside a detached header (uncompressed, as write_image sets it).
fs::path predicted_data_file(const fs::path& target) {
  fs::path d = target;
  d.replace_extension(".raw");
  return d;
}

// Writes into a fresh temporary folder beside the target, then renames the file(s) into place:
// a reader never sees a half-written file. For detached formats (.nhdr, .mhd) the data file
// is moved first and the header last.
class AtomicWrite {
 public:
  explicit AtomicWrite(const std::string& path) : target_(fs::absolute(path)) {
    const fs::path parent = target_.parent_path();
    std::error_code ec;
    if (!fs::is_directory(parent, ec))
      throw Error(path + ": cannot write: folder " + parent.string() + " does not exist");
    std::string templ = (parent / (".hpcm-tmp-XXXXXX")).string();
    if (!mkdtemp(templ.data())) throw Error(path + ": cannot write: no permission to create files in " + parent.string());
    tmpdir_ = templ;
  }
  ~AtomicWrite() {
    std::error_code ec;
    if (!tmpdir_.empty()) fs::remove_all(tmpdir_, ec);
  }
  std::string temp_path() const { return (tmpdir_ / target_.filename()).string(); }
  /// Flushes every written file to the disk: a full disk or an I/O error that the writer did not
  /// report (ITK's NIfTI and MetaImage writers ignore failed writes) is an error here.
  void sync() const {
    for (const auto& e : fs::directory_iterator(tmpdir_)) {
      const int fd = ::open(e.path().c_str(), O_RDONLY);
      const bool ok = fd >= 0 && ::fsync(fd) == 0;
      const int err = errno;
      if (fd >= 0) ::close(fd);
      if (!ok) throw Error(target_.string() + ": write failed (" + std::strerror(err) + ")");
    }
  }
  void commit() {
    std::vector<fs::path> files;
    for (const auto& e : fs::directory_iterator(tmpdir_)) files.push_back(e.path());
    std::stable_partition(files.begin(), files.end(), [&](const fs::path& p) { return p.filename() != target_.filename(); });
    for (const fs::path& p : files)
      if (p.filename() != target_.filename()) check_data_file_free(target_, target_.parent_path() / p.filename());
    for (const fs::path& p : files) {
      std::error_code ec;
      fs::rename(p, target_.parent_path() / p.filename(), ec);
      if (ec) throw Error(target_.string() + ": cannot move the written file into place: " + ec.message());
    }
  }

 private:
  fs::path target_;
  fs::path tmpdir_;
};

// The voxels of the first 3-D volume of a file whose information `io` has read, as the file
// stores them (native byte order, components interleaved): what ImageFileReader reads for an
// image of the file's own pixel type. The whole file is read (non-streaming IOs read all of
// it), then cut to its first volume.
std::vector<unsigned char> read_first_volume(itk::ImageIOBase& io) {
  const unsigned nd = io.GetNumberOfDimensions();
  itk::ImageIORegion region(nd);
  std::size_t voxels = 1, volume = 1;
  for (unsigned a = 0; a < nd; ++a) {
    region.SetIndex(a, 0);
    region.SetSize(a, io.GetDimensions(a));
    voxels *= io.GetDimensions(a);
    if (a < 3) volume *= io.GetDimensions(a);
  }
  io.SetIORegion(region);
  const std::size_t pixel_bytes = io.GetComponentSize() * io.GetNumberOfComponents();
  std::vector<unsigned char> bytes(voxels * pixel_bytes);
  io.Read(bytes.data());
  bytes.resize(volume * pixel_bytes);
  return bytes;
}

// Reads a just-written file back and compares it with what was meant to be written, bit for
// bit: a file cut short (disk full, a file size limit) whose writer still reported success is
// an error, never a result. Through the ImageIO alone: an ITK reader per written pixel type
// cost more compile time than the rest of this check.
void verify_written(const void* data, const std::array<std::size_t, 3>& dims, unsigned components,
                    std::size_t component_bytes, const std::string& written, Format f, const std::string& path,
                    const char* what) {
  const std::string failed = path + ": write failed (disk full?): read back, the written file ";
  itk::ImageIOBase::Pointer back = make_io(f);
  std::vector<unsigned char> bytes;
  try {
    back->SetFileName(written);
    back->ReadImageInformation();
    bool same_size = back->GetNumberOfDimensions() >= 3 && back->GetNumberOfComponents() == components &&
                     back->GetComponentSize() == component_bytes;
    for (unsigned a = 0; same_size && a < 3; ++a) same_size = back->GetDimensions(a) == dims[a];
    if (!same_size) throw Error(failed + "has another size than " + std::string(what));
    bytes = read_first_volume(*back);
  } catch (const itk::ExceptionObject& e) {
    throw Error(failed + "is unreadable: " + one_line(e));
  }
  if (bytes.size() != dims[0] * dims[1] * dims[2] * components * component_bytes ||
      std::memcmp(bytes.data(), data, bytes.size()) != 0)
    throw Error(failed + "differs from " + std::string(what) + " it was meant to hold");
}

// The format of `path`, one of `allowed` for writing `what`.
Format output_format(const std::string& path, const std::vector<Format>& allowed, const char* what) {
  const Format f = detail::format_of(path);
  if (std::find(allowed.begin(), allowed.end(), f) == allowed.end()) {
    std::string list;
    for (Format a : allowed) list += (list.empty() ? "" : ", ") + detail::extension_of(a);
    throw Error(path + ": unsupported extension for " + what + " (supported: " + list + ")");
  }
  return f;
}

// Single-file formats are compressed; detached ones (.nhdr, .mhd) keep raw data.
bool compressed(Format f) { return f == Format::NiftiGz || f == Format::Nrrd || f == Format::Mha; }

// The origin and direction as ImageFileWriter writes them from an itk::Image given these, so that
// the files stay byte for byte what they were (signs of zero included): the image keeps its
// initial identity entry (and its origin 0) where the value equals it, and the writer's origin is
// the physical point of index 0, origin + (direction * diag(spacing)) * 0, summed as ITK does.
struct WrittenGeometry {
  std::array<double, 3> origin;
  std::array<double, 9> direction;  ///< row-major
};
WrittenGeometry as_itk_writes(const std::array<double, 3>& spacing, const std::array<double, 3>& origin,
                              const std::array<double, 9>& direction) {
  WrittenGeometry w;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) {
      const double initial = r == c ? 1.0 : 0.0;
      w.direction[r * 3 + c] = direction[r * 3 + c] == initial ? initial : direction[r * 3 + c];
    }
  const bool zero_origin = origin[0] == 0.0 && origin[1] == 0.0 && origin[2] == 0.0;
  for (int r = 0; r < 3; ++r) {
    w.origin[r] = zero_origin ? 0.0 : origin[r];
    for (int c = 0; c < 3; ++c) {
      double m = w.direction[r * 3] * (c == 0 ? spacing[0] : 0.0);
      for (int k = 1; k < 3; ++k) m += w.direction[r * 3 + k] * (k == c ? spacing[c] : 0.0);
      w.origin[r] += m * 0.0;
    }
  }
  return w;
}

// Writes voxels whose pixel type `io` has been given, as ImageFileWriter writes an itk::Image in
// one piece, through the format's ImageIO alone (a writer per pixel type cost more compile
// time than the rest of this file's writing), then reads the file back and compares it.
// `direction` is row-major (row a, column c: direction[a * 3 + c]).
void write_voxels(itk::ImageIOBase& io, Format f, const std::array<std::size_t, 3>& dims,
                  const std::array<double, 3>& spacing, const std::array<double, 3>& origin,
                  const std::array<double, 9>& direction, const itk::MetaDataDictionary& dictionary,
                  const void* data, const std::string& path, const char* what) {
  AtomicWrite aw(path);
  const WrittenGeometry w = as_itk_writes(spacing, origin, direction);
  io.SetNumberOfDimensions(3);
  itk::ImageIORegion region(3);
  for (unsigned a = 0; a < 3; ++a) {
    io.SetDimensions(a, dims[a]);
    io.SetSpacing(a, spacing[a]);
    io.SetOrigin(a, w.origin[a]);
    io.SetDirection(a, std::vector<double>{w.direction[a], w.direction[3 + a], w.direction[6 + a]});  // column a
    region.SetIndex(a, 0);
    region.SetSize(a, dims[a]);
  }
  io.SetUseCompression(compressed(f));
  io.SetMetaDataDictionary(dictionary);
  io.SetFileName(aw.temp_path());
  io.SetIORegion(region);
  try {
    io.Write(data);
  } catch (const itk::ExceptionObject& e) {
    throw Error(path + ": cannot write " + what + ": " + one_line(e));
  }
  aw.sync();
  verify_written(data, dims, io.GetNumberOfComponents(), io.GetComponentSize(), aw.temp_path(), f, path, what);
  aw.commit();
}

template <class TImage>
void write_image(TImage* img, const std::string& path, const std::vector<Format>& allowed, const char* what) {
  const Format f = output_format(path, allowed, what);
  itk::ImageIOBase::Pointer io = make_io(f);
  io->SetPixelTypeInfo(static_cast<const typename TImage::PixelType*>(nullptr));
  const auto size = img->GetLargestPossibleRegion().GetSize();
  const Grid g = grid_of_image(img);
  write_voxels(*io, f, {size[0], size[1], size[2]}, g.spacing, g.origin, g.direction, img->GetMetaDataDictionary(),
               img->GetBufferPointer(), path, what);
}

template <class TImage>
typename TImage::Pointer make_image(Int3 dims, const std::array<double, 3>& spacing, const std::array<double, 3>& origin,
                                    const std::array<double, 9>& direction) {
  auto img = TImage::New();
  typename TImage::RegionType region;
  typename TImage::SizeType size;
  size[0] = dims.x, size[1] = dims.y, size[2] = dims.z;
  region.SetSize(size);
  img->SetRegions(region);
  typename TImage::SpacingType sp;
  typename TImage::PointType org;
  typename TImage::DirectionType dir;
  for (int a = 0; a < 3; ++a) {
    sp[a] = spacing[a];
    org[a] = origin[a];
    for (int c = 0; c < 3; ++c) dir(a, c) = direction[a * 3 + c];
  }
  img->SetSpacing(sp);
  img->SetOrigin(org);
  img->SetDirection(dir);
  return img;
}

const std::vector<Format> kVolumeFormats = {Format::Nifti, Format::NiftiGz, Format::Nrrd,
                                            Format::Nhdr,  Format::Mha,     Format::Mhd};

void write_scalar(const std::vector<float>& values, Int3 dims, const std::array<double, 3>& spacing,
                  const std::array<double, 3>& origin, const std::array<double, 9>& direction, const std::string& path) {
  // Integer HU within int16 are written as int16 (what CT readers expect), anything else as float.
  bool integral = true;
  for (float v : values)
    if (!(v == std::nearbyint(v) && v >= -32768.0f && v <= 32767.0f)) {
      integral = false;
      break;
    }
  if (integral) {
    using ShortImage = itk::Image<short, 3>;
    auto img = make_image<ShortImage>(dims, spacing, origin, direction);
    img->Allocate();
    short* p = img->GetBufferPointer();
    for (std::size_t i = 0; i < values.size(); ++i) p[i] = static_cast<short>(values[i]);
    write_image(img.GetPointer(), path, kVolumeFormats, "a volume");
  } else {
    auto img = make_image<FloatImage>(dims, spacing, origin, direction);
    img->Allocate();
    std::copy(values.begin(), values.end(), img->GetBufferPointer());
    write_image(img.GetPointer(), path, kVolumeFormats, "a volume");
  }
}

}  // namespace

// ---- public API ----------------------------------------------------------------------------

Volume read_volume_as_stored(const std::string& path, const ReadOptions& opt) {
  if (path.empty()) throw Error("no input volume given (supported: " + std::string(kSupported) + ")");
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (ec || !fs::exists(st)) throw Error(path + ": no such file or directory");
  std::vector<std::string> warnings;
  Volume v;
  {
    LibraryOutputCapture capture;
    try {
      if (fs::is_directory(st)) {
        v = read_dicom_dir(path, opt, warnings);
      } else {
        if (!fs::is_regular_file(st)) throw Error(path + ": not a regular file or directory");
        if (!opt.series_uid.empty())
          throw Error(path + ": --series applies only to a DICOM series directory, not to a file");
        v = read_file(path, warnings);
      }
    } catch (const Error& e) {
      throw Error(e.what() + capture.detail());
    } catch (const itk::ExceptionObject& e) {
      throw Error(path + ": " + one_line(e) + capture.detail());
    } catch (const fs::filesystem_error& e) {
      throw Error(path + ": " + e.what() + capture.detail());
    }
  }
  for (const std::string& w : warnings) {
    if (opt.warn)
      opt.warn(w);
    else
      std::fprintf(stderr, "hpcm: warning: %s\n", w.c_str());
  }
  return v;
}

std::string nifti_geometry_source(const std::string& path) {
  const Format f = detail::format_of(path);
  if (f != Format::Nifti && f != Format::NiftiGz) return "";
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return "";
  return detail::nifti_geometry_source(read_nifti_header(path));
}

Volume read_volume(const std::string& path, const ReadOptions& opt) {
  return to_lps_order(read_volume_as_stored(path, opt));
}

Input load_input(const std::string& path, const InputOptions& opt) {
  ReadOptions ro;
  ro.series_uid = opt.series_uid;
  ro.dicom_duplicates = opt.dicom_duplicates;
  ro.dicom_skip_unreadable = opt.dicom_skip_unreadable;
  return prepare_input(read_volume_as_stored(path, ro), opt, path);
}

std::vector<DicomSeriesInfo> list_dicom_series(const std::string& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw Error(dir + ": not a directory");
  LibraryOutputCapture capture;
  try {
    return scan_dicom_dir(dir).info;
  } catch (const Error& e) {
    throw Error(e.what() + capture.detail());
  }
}

void check_output_path(const std::string& path) {
  const Format f = detail::format_of(path);
  if (std::find(kVolumeFormats.begin(), kVolumeFormats.end(), f) == kVolumeFormats.end())
    throw Error(path + ": unsupported extension for a volume (supported: .nii, .nii.gz, .nrrd, .nhdr, .mha, .mhd)");
  const fs::path target = fs::absolute(path);
  std::error_code ec;
  if (fs::is_directory(target, ec)) throw Error(path + ": is a folder; give a file name such as " + path + "/ct.nii.gz");
  const fs::path parent = target.parent_path();
  if (!fs::is_directory(parent, ec)) throw Error(path + ": cannot write: folder " + parent.string() + " does not exist");
  if (::access(parent.c_str(), W_OK | X_OK) != 0)
    throw Error(path + ": cannot write into " + parent.string() + " (" + std::strerror(errno) + ")");
  if (f == Format::Nhdr || f == Format::Mhd) check_data_file_free(target, predicted_data_file(target));
}

void write_volume(const Volume& v, const std::string& path) {
  validate_volume(v, path);
  write_scalar(v.hu, v.dims, v.spacing, v.origin, v.direction, path);
}

void write_displacement_field(const Input& in, const Model& m, const std::vector<Vec3>& disp, const std::string& path) {
  const std::vector<float> u = displacement_on_input_grid(in, m, disp);
  using VecImage = itk::Image<itk::Vector<float, 3>, 3>;
  static_assert(sizeof(itk::Vector<float, 3>) == 3 * sizeof(float), "itk::Vector<float, 3> is three packed floats");
  const Grid& g = in.lattice_grid;
  auto img = make_image<VecImage>(g.dims, g.spacing, g.origin, g.direction);
  img->Allocate();
  std::memcpy(static_cast<void*>(img->GetBufferPointer()), u.data(), u.size() * sizeof(float));
  const Format f = detail::format_of(path);
  if (f == Format::Nrrd || f == Format::Nhdr)
    // 3D Slicer reads this NRRD key (since September 2025): a modeling (to-parent) transform
    // moves rest positions to deformed ones, which is what this field stores.
    itk::EncapsulateMetaData<std::string>(img->GetMetaDataDictionary(), "displacement field type", "modeling");
  write_image(img.GetPointer(), path, {Format::Nifti, Format::NiftiGz, Format::Nrrd, Format::Mha},
              "a displacement field");
}

InverseMappingStats write_deformed_volume(const Volume& target, const Model& m, const std::vector<Vec3>& disp,
                                          const std::string& path) {
  validate_volume(target, path);
  InverseMappingStats stats;
  const std::vector<float> hu = detail::resample_deformed(target, m, disp, detail::kInverseMappingIterations,
                                                          detail::kInverseMappingNewtonIterations, &stats);
  write_scalar(hu, target.dims, target.spacing, target.origin, target.direction, path);
  return stats;
}

InverseMappingStats write_deformed_volume(const Input& in, const Model& m, const std::vector<Vec3>& disp,
                                          const std::string& path) {
  detail::check_model_matches(in, m, path + ": deformed CT");
  return write_deformed_volume(in.stored, m, disp, path);
}

void write_label_map(const Input& in, const Model& m, const std::string& path) {
  detail::check_model_matches(in, m, path + ": label map");
  if (static_cast<Index>(m.tissue.size()) != m.size())
    throw Error(path + ": label map: the model has " + std::to_string(m.tissue.size()) + " tissue labels for " +
                std::to_string(m.size()) + " elements");
  std::vector<unsigned char> classes(in.lattice_grid.size());
  detail::for_each_lattice_voxel(in.lattice_grid.dims, in.order, [&](std::int64_t l, std::int64_t s) {
    classes[s] = m.counted(l) ? m.tissue[l] : kOutsideLabel;  // SPEC §3: outside elements have their own label
  });
  write_class_labels(in.lattice_grid, classes, path);
}

void write_class_labels(const Grid& g, const std::vector<unsigned char>& classes, const std::string& path) {
  if (classes.size() != g.size())
    throw Error(path + ": label map: " + std::to_string(classes.size()) + " labels for a grid of " +
                std::to_string(g.size()) + " voxels");
  using LabelImage = itk::Image<unsigned char, 3>;
  auto img = make_image<LabelImage>(g.dims, g.spacing, g.origin, g.direction);
  img->Allocate();
  std::copy(classes.begin(), classes.end(), img->GetBufferPointer());
  write_image(img.GetPointer(), path, kVolumeFormats, "a label map");
  // Colour table in Slicer's .ctbl format ("index name R G B A"), beside the label map.
  const Format f = detail::format_of(path);
  std::string base = path.substr(0, path.size() - detail::extension_of(f).size());
  const std::string ctbl = base + ".ctbl";
  AtomicWrite aw(ctbl);
  {
    std::ofstream out(aw.temp_path());
    out << "# hpcm tissue classes: index name R G B A\n";
    static const int rgba[kTissueCount][4] = {{0, 0, 0, 0}, {230, 200, 150, 255}, {200, 70, 60, 255}, {241, 214, 145, 255}};
    for (int t = 0; t < kTissueCount; ++t)
      out << t << ' ' << tissue_name(t) << ' ' << rgba[t][0] << ' ' << rgba[t][1] << ' ' << rgba[t][2] << ' '
          << rgba[t][3] << '\n';
    out << int(kOutsideLabel) << " outside 90 110 140 255\n";  // not the body (air noise, the table)
    out.close();
    if (!out) throw Error(ctbl + ": cannot write the colour table (disk full?)");
  }
  aw.sync();
  aw.commit();
}

void write_pullback_field(const Grid& g, const std::vector<float>& pullback_mm, const std::string& path) {
  if (pullback_mm.size() != 3 * g.size())
    throw Error(path + ": pull-back field: " + std::to_string(pullback_mm.size()) + " values for a grid of " +
                std::to_string(g.size()) + " voxels x 3 components");
  using VecImage = itk::Image<itk::Vector<float, 3>, 3>;
  auto img = make_image<VecImage>(g.dims, g.spacing, g.origin, g.direction);
  img->Allocate();
  std::memcpy(static_cast<void*>(img->GetBufferPointer()), pullback_mm.data(), pullback_mm.size() * sizeof(float));
  const Format f = detail::format_of(path);
  if (f == Format::Nrrd || f == Format::Nhdr)
    // Slicer's key: a resampling (from-parent) field says where each output voxel samples from.
    itk::EncapsulateMetaData<std::string>(img->GetMetaDataDictionary(), "displacement field type", "resampling");
  write_image(img.GetPointer(), path, {Format::Nifti, Format::NiftiGz, Format::Nrrd, Format::Mha},
              "a pull-back displacement field");
}

// Label maps are read and written as the file stores them, byte for byte, through the ImageIO
// alone: an ITK reader and writer per integer type (ten of each) doubled this file's compile time.
namespace {
bool is_integer(itk::IOComponentEnum c) {
  using C = itk::IOComponentEnum;
  switch (c) {
    case C::UCHAR: case C::CHAR: case C::USHORT: case C::SHORT: case C::UINT:
    case C::INT: case C::ULONG: case C::LONG: case C::ULONGLONG: case C::LONGLONG: return true;
    default: return false;
  }
}

// Writes a label map's voxels in its own integer type, as ImageFileWriter writes an itk::Image
// of that type (one piece), then reads the file back and compares it bit for bit.
void write_label_file(const LabelMap& map, itk::IOComponentEnum type, const std::string& path) {
  const char* what = "a label map";
  const Format f = output_format(path, kVolumeFormats, what);
  itk::ImageIOBase::Pointer io = make_io(f);
  io->SetPixelType(itk::IOPixelEnum::SCALAR);
  io->SetComponentType(type);
  io->SetNumberOfComponents(1);
  if (io->GetComponentSize() != static_cast<std::size_t>(map.bytes))
    throw Error(path + ": label map: " + std::to_string(map.bytes) + " bytes per voxel, but " + map.component_type +
                " has " + std::to_string(io->GetComponentSize()));
  const Grid& g = map.grid;
  write_voxels(*io, f, {std::size_t(g.dims.x), std::size_t(g.dims.y), std::size_t(g.dims.z)}, g.spacing, g.origin,
               g.direction, itk::MetaDataDictionary(), map.data.data(), path, what);
}
}  // namespace

LabelMap read_label_map(const std::string& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw Error(path + ": label map: no such file");
  const Format f = detail::format_of(path);
  if (f == Format::Unknown) throw Error(path + ": label map: unknown format (supported: .nii, .nii.gz, .nrrd, .nhdr, .mha, .mhd)");
  LibraryOutputCapture capture;
  try {
    std::optional<detail::Geometry> nifti_grid;  // nibabel's affine rule, as for the CT
    if (f == Format::Nifti || f == Format::NiftiGz) {
      const detail::NiftiHeader h = read_nifti_header(path);
      const bool scaled = h.scl_slope != 0 && (h.scl_slope != 1 || h.scl_inter != 0);
      if (scaled)
        throw Error(path + ": label map: NIfTI scl_slope " + std::to_string(h.scl_slope) + " / scl_inter " +
                    std::to_string(h.scl_inter) + " scale its values; a label map needs integer labels as stored "
                    "(scl_slope 0 or 1, scl_inter 0)");
      nifti_grid = detail::nifti_geometry(path, h);
    }
    if (f == Format::Nrrd || f == Format::Nhdr) detail::check_nrrd_header(path, read_text_header(path, true));
    if (f == Format::Mha || f == Format::Mhd) detail::check_metaimage_header(path, read_text_header(path, false));
    itk::ImageIOBase::Pointer io = make_io(f);
    if (!io->CanReadFile(path.c_str())) throw Error(path + ": label map: not a readable " + std::string(detail::format_name(f)) + " file");
    io->SetFileName(path);
    io->ReadImageInformation();
    const unsigned nd = io->GetNumberOfDimensions();
    if (io->GetNumberOfComponents() != 1 || io->GetPixelType() != itk::IOPixelEnum::SCALAR)
      throw Error(path + ": label map: " + itk::ImageIOBase::GetPixelTypeAsString(io->GetPixelType()) + " image with " +
                  std::to_string(io->GetNumberOfComponents()) + " components per voxel; a label map has one integer per voxel");
    if (nd < 3 || (nd > 3 && io->GetDimensions(3) != 1))
      throw Error(path + ": label map: a " + std::to_string(nd) + "-D image; a 3-D label map is needed");
    check_read_memory(path, {io->GetDimensions(0), io->GetDimensions(1), io->GetDimensions(2)},
                      double(io->GetComponentSize()));
    LabelMap map;
    map.source = path;
    map.component_type = itk::ImageIOBase::GetComponentTypeAsString(io->GetComponentType());
    if (!is_integer(io->GetComponentType()))
      throw Error(path + ": label map: voxels are " + map.component_type +
                  "; a label map needs an integer type (uint8/int8 .. uint64/int64): labels are never interpolated");
    // The grid as ITK's reader gives it to an image (negative spacing flips the axis, ...).
    auto reader = itk::ImageFileReader<FloatImage>::New();
    reader->SetImageIO(io);
    reader->SetFileName(path);
    reader->UpdateOutputInformation();
    map.grid = grid_of_image(reader->GetOutput());
    map.bytes = static_cast<int>(io->GetComponentSize());
    map.data = read_first_volume(*io);
    if (nifti_grid) {
      map.grid.spacing = nifti_grid->spacing;
      map.grid.origin = nifti_grid->origin;
      map.grid.direction = nifti_grid->direction;
    }
    return map;
  } catch (const Error& e) {
    throw Error(e.what() + capture.detail());
  } catch (const itk::ExceptionObject& e) {
    throw Error(path + ": label map: " + one_line(e) + capture.detail());
  }
}

void write_label_values(const LabelMap& map, const std::string& path) {
  if (map.data.size() != map.grid.size() * static_cast<std::size_t>(map.bytes))
    throw Error(path + ": label map: " + std::to_string(map.data.size()) + " bytes for a grid of " +
                std::to_string(map.grid.size()) + " voxels");
  const auto type = itk::ImageIOBase::GetComponentTypeFromString(map.component_type);
  if (!is_integer(type)) throw Error(path + ": label map: " + map.component_type + " is not an integer type");
  write_label_file(map, type, path);
}

namespace detail {
RawImage read_raw_image(const std::string& path) {
  const Format f = format_of(path);
  itk::ImageIOBase::Pointer io = make_io(f);
  if (!io) throw Error(path + ": unknown format");
  RawImage r;
  try {
    io->SetFileName(path);
    io->ReadImageInformation();
    r.dimensions = int(io->GetNumberOfDimensions());
    r.components = int(io->GetNumberOfComponents());
    r.component_type = itk::ImageIOBase::GetComponentTypeAsString(io->GetComponentType());
    r.pixel_type = itk::ImageIOBase::GetPixelTypeAsString(io->GetPixelType());
    using VImage = itk::VectorImage<float, 3>;
    auto reader = itk::ImageFileReader<VImage>::New();
    reader->SetImageIO(io);
    reader->SetFileName(path);
    reader->Update();
    VImage* img = reader->GetOutput();
    const auto size = img->GetLargestPossibleRegion().GetSize();
    r.geometry = grid_of_image(img);
    const std::size_t n = std::size_t(size[0]) * size[1] * size[2] * img->GetNumberOfComponentsPerPixel();
    r.data.assign(img->GetBufferPointer(), img->GetBufferPointer() + n);
  } catch (const itk::ExceptionObject& e) {
    throw Error(path + ": " + one_line(e));
  }
  return r;
}
}  // namespace detail

}  // namespace hpcm::io
