// hpcm::io on ITK 5: reading NIfTI / NRRD / MetaImage files and DICOM series (GDCM, including
// JPEG-2000), writing volumes, displacement fields and label maps for 3D Slicer.
// All ITK code of the project is in this one translation unit (compile time).
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <unistd.h>

#include <itkGDCMImageIO.h>
#include <itkGDCMSeriesFileNames.h>
#include <itkImage.h>
#include <itkImageFileReader.h>
#include <itkImageFileWriter.h>
#include <itkImageSeriesReader.h>
#include <itkMetaDataObject.h>
#include <itkMetaImageIO.h>
#include <itkNiftiImageIO.h>
#include <itkNrrdImageIO.h>
#include <itkVector.h>
#include <itkVectorImage.h>
#include <zlib.h>

#include "hpcm/io.hpp"
#include "hpcm/tissue.hpp"
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

// Checks the header of a scalar 3-D volume: components, dimensionality, memory.
// `extra_bytes_per_voxel`: what reading costs beyond the float result (file-type buffer).
Int3 check_header(const std::string& path, itk::ImageIOBase& io, std::size_t nslices_override = 0) {
  const unsigned nd = io.GetNumberOfDimensions();
  std::vector<std::size_t> d;
  for (unsigned a = 0; a < nd; ++a) d.push_back(io.GetDimensions(a));
  if (nslices_override) {
    d.resize(3, 1);
    d[2] = nslices_override;
  }
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
  const double n = double(d[0]) * double(d[1]) * double(d[2]);
  const double per_voxel = 2.0 * sizeof(float) + io.GetComponentSize() + sizeof(float);  // ITK buffers + Volume
  const double need = n * per_voxel;
  const double avail = double(detail::available_memory_bytes());
  if (n > 2147483647.0 || need > avail)
    throw Error(path + ": volume " + dims_text({d[0], d[1], d[2]}) + " is too large: reading needs " +
                detail::format_bytes(need) + " (" + std::to_string(static_cast<unsigned long long>(need)) +
                " bytes) but " + detail::format_bytes(avail) + " of memory are available" +
                (n > 2147483647.0 ? " and at most 2^31-1 voxels are supported" : "") +
                "; crop it or down-sample it first");
  return {int(d[0]), int(d[1]), int(d[2])};
}

// ITK float image (file index order, LPS geometry) -> checked Volume in the same order.
Volume finish(const std::string& path, FloatImage* img) {
  detail::Geometry g;
  const auto size = img->GetLargestPossibleRegion().GetSize();
  g.dims = {int(size[0]), int(size[1]), int(size[2])};
  for (int a = 0; a < 3; ++a) {
    g.spacing[a] = img->GetSpacing()[a];
    g.origin[a] = img->GetOrigin()[a];
    for (int c = 0; c < 3; ++c) g.direction[a * 3 + c] = img->GetDirection()(a, c);
  }
  for (int a = 0; a < 3; ++a)
    if (!(g.spacing[a] > 0) || !std::isfinite(g.spacing[a]))
      throw Error(path + ": voxel spacing " + std::to_string(g.spacing[a]) + " along axis " + std::to_string(a) +
                  " is not a positive number");
  const float* data = img->GetBufferPointer();
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
  return v;
}

// ITK's NIfTI and MetaImage readers do not report a short data part (they print to stderr or
// leave garbage): check that the file holds all the bytes its header announces.
void check_complete(const std::string& path, Format f, itk::ImageIOBase& io) {
  const double data_bytes = double(io.GetImageSizeInBytes());
  const std::string name = detail::format_name(f);
  auto truncated = [&](double have, double need) {
    throw Error(path + ": truncated or corrupt " + name + " file: " + std::to_string(static_cast<long long>(have)) +
                " bytes where the header announces " + std::to_string(static_cast<long long>(need)));
  };
  if (f == Format::Nifti || f == Format::NiftiGz) {
    gzFile gz = gzopen(path.c_str(), "rb");  // also reads uncompressed files
    if (!gz) throw Error(path + ": cannot open");
    std::vector<unsigned char> buf(1 << 16);
    long long total = 0;
    double vox_offset = -1;
    for (;;) {
      const int n = gzread(gz, buf.data(), unsigned(buf.size()));
      if (n <= 0) break;
      if (total == 0 && n >= 348) {
        std::int32_t sz;
        std::memcpy(&sz, buf.data(), 4);
        const bool swap = sz != 348 && sz != 540;
        auto rd = [&](std::size_t off, std::size_t len) {
          unsigned char b[8];
          std::memcpy(b, buf.data() + off, len);
          if (swap) std::reverse(b, b + len);
          return std::vector<unsigned char>(b, b + len);
        };
        if (swap) std::reverse(reinterpret_cast<unsigned char*>(&sz), reinterpret_cast<unsigned char*>(&sz) + 4);
        if (sz == 348) {
          float vo;
          std::memcpy(&vo, rd(108, 4).data(), 4);
          vox_offset = vo;
        } else if (sz == 540 && n >= 540) {
          std::int64_t vo;
          std::memcpy(&vo, rd(168, 8).data(), 8);
          vox_offset = double(vo);
        }
      }
      total += n;
    }
    int err = Z_OK;
    const char* msg = gzerror(gz, &err);
    const std::string zmsg = (err != Z_OK && err != Z_STREAM_END && msg) ? msg : "";
    gzclose(gz);
    if (!zmsg.empty()) throw Error(path + ": truncated or corrupt " + name + " file (" + zmsg + ")");
    if (vox_offset >= 0 && double(total) < vox_offset + data_bytes) truncated(double(total), vox_offset + data_bytes);
    return;
  }
  if (f == Format::Mha || f == Format::Mhd) {
    std::ifstream in(path, std::ios::binary);
    std::string line, data_file;
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
        break;
      }
    }
    double have = -1;
    if (data_file == "LOCAL" || data_file == "Local" || data_file == "local") {
      const std::streamoff off = in.tellg();
      if (off >= 0) have = double(fs::file_size(path)) - double(off);
    } else if (!data_file.empty() && data_file.find('%') == std::string::npos && data_file.find(' ') == std::string::npos &&
               data_file != "LIST") {
      const fs::path p = fs::path(path).parent_path() / data_file;
      std::error_code ec;
      const auto sz = fs::file_size(p, ec);
      if (ec) throw Error(path + ": its data file " + p.string() + " is missing");
      have = double(sz);
    }
    const double need = compressed ? compressed_size : data_bytes;
    if (have >= 0 && need > 0 && have < need) truncated(have, need);
  }
}

Volume read_file(const std::string& path) {
  const Format f = detail::format_of(path);
  if (f == Format::Unknown) {
    if (looks_like_dicom_file(path))
      throw Error(path + ": a single DICOM file; give the directory that holds the series instead");
    throw Error(path + ": unknown volume format (supported: " + kSupported + ")");
  }
  itk::ImageIOBase::Pointer io = make_io(f);
  const std::string name = detail::format_name(f);
  if (fs::file_size(path) == 0) throw Error(path + ": empty file, not a " + name + " volume");
  if (!io->CanReadFile(path.c_str()))
    throw Error(path + ": not a readable " + name + " file (corrupt or truncated header)");
  try {
    io->SetFileName(path);
    io->ReadImageInformation();
  } catch (const itk::ExceptionObject& e) {
    throw Error(path + ": corrupt " + name + " header: " + one_line(e));
  }
  check_header(path, *io);
  check_complete(path, f, *io);
  auto reader = itk::ImageFileReader<FloatImage>::New();
  reader->SetImageIO(io);
  reader->SetFileName(path);
  try {
    reader->Update();
  } catch (const itk::ExceptionObject& e) {
    throw Error(path + ": truncated or corrupt " + name + " file: " + one_line(e));
  }
  return finish(path, reader->GetOutput());
}

struct SeriesFiles {
  detail::Geometry g;
  std::vector<DicomSeriesInfo> info;
  std::vector<std::vector<std::string>> files;
};

SeriesFiles scan_dicom_dir(const std::string& dir) {
  std::error_code ec;
  std::size_t entries = 0;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    (void)e;
    ++entries;
  }
  if (ec) throw Error(dir + ": cannot list the directory: " + ec.message());
  if (entries == 0) throw Error(dir + ": empty directory; expected the files of a DICOM series");
  SeriesFiles out;
  auto names = itk::GDCMSeriesFileNames::New();
  names->SetGlobalWarningDisplay(false);
  names->SetUseSeriesDetails(false);
  names->SetRecursive(false);
  try {
    names->SetDirectory(dir);
    for (const std::string& uid : names->GetSeriesUIDs()) {
      std::vector<std::string> files = names->GetFileNames(uid);
      if (files.empty()) continue;
      DicomSeriesInfo s;
      s.uid = uid;
      s.files = int(files.size());
      auto dio = itk::GDCMImageIO::New();
      dio->SetGlobalWarningDisplay(false);
      dio->SetFileName(files.front());
      try {
        dio->ReadImageInformation();
        std::string v;
        if (dio->GetValueFromTag("0008|0060", v)) s.modality = trim(v);
        if (dio->GetValueFromTag("0008|103e", v)) s.description = trim(v);
        if (dio->GetValueFromTag("0020|000e", v) && !trim(v).empty()) s.uid = trim(v);
        s.columns = int(dio->GetDimensions(0));
        s.rows = int(dio->GetDimensions(1));
      } catch (const itk::ExceptionObject&) {
        continue;  // not an image we can read: not listed
      }
      out.info.push_back(s);
      out.files.push_back(std::move(files));
    }
  } catch (const itk::ExceptionObject& e) {
    throw Error(dir + ": cannot scan the DICOM directory: " + one_line(e));
  }
  if (out.info.empty())
    throw Error(dir + ": no DICOM image files among its " + std::to_string(entries) + " entries");
  return out;
}

std::string series_line(const DicomSeriesInfo& s) {
  std::string t = (s.uid.empty() ? std::string("<empty SeriesInstanceUID>") : s.uid) + " (" + (s.modality.empty() ? "?" : s.modality) + ", " + std::to_string(s.files) +
                  " slices " + std::to_string(s.columns) + "x" + std::to_string(s.rows);
  if (!s.description.empty()) t += ", '" + s.description + "'";
  return t + ")";
}

Volume read_dicom_dir(const std::string& dir, const ReadOptions& opt) {
  SeriesFiles sf = scan_dicom_dir(dir);
  std::vector<std::size_t> ct;
  for (std::size_t i = 0; i < sf.info.size(); ++i)
    if (sf.info[i].modality == "CT") ct.push_back(i);
  std::size_t pick = 0;
  if (!opt.series_uid.empty()) {
    bool found = false;
    for (std::size_t i = 0; i < sf.info.size() && !found; ++i)
      if (sf.info[i].uid == opt.series_uid) pick = i, found = true;
    if (!found) {
      std::string list;
      for (const auto& s : sf.info) list += (list.empty() ? "" : "; ") + series_line(s);
      throw Error(dir + ": no series with --series " + opt.series_uid + " (the directory has: " + list + ")");
    }
    if (sf.info[pick].modality != "CT")
      throw Error(dir + ": series " + opt.series_uid + " is " +
                  (sf.info[pick].modality.empty() ? std::string("of unknown modality") : sf.info[pick].modality) +
                  ", not CT; HU values need a CT series");
  } else {
    if (ct.empty()) {
      std::string list;
      for (const auto& s : sf.info) list += (list.empty() ? "" : "; ") + series_line(s);
      throw Error(dir + ": no CT series in this DICOM directory (found: " + list + ")");
    }
    if (ct.size() > 1) {
      std::string list;
      for (std::size_t i : ct) list += (list.empty() ? "" : "; ") + series_line(sf.info[i]);
      throw Error(dir + ": " + std::to_string(ct.size()) + " CT series; choose one with --series UID: " + list);
    }
    pick = ct.front();
  }
  const std::vector<std::string>& files = sf.files[pick];
  auto dio = itk::GDCMImageIO::New();
  dio->SetGlobalWarningDisplay(false);
  try {
    dio->SetFileName(files.front());
    dio->ReadImageInformation();
  } catch (const itk::ExceptionObject& e) {
    throw Error(dir + ": corrupt DICOM file " + files.front() + ": " + one_line(e));
  }
  check_header(dir, *dio, files.size());
  auto reader = itk::ImageSeriesReader<FloatImage>::New();
  reader->SetImageIO(dio);
  reader->SetFileNames(files);
  try {
    reader->Update();  // GDCM applies RescaleSlope/Intercept: values are HU
  } catch (const itk::ExceptionObject& e) {
    throw Error(dir + ": cannot read DICOM series " + sf.info[pick].uid + ": " + one_line(e));
  }
  return finish(dir, reader->GetOutput());
}

// ---- writing -------------------------------------------------------------------------------

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
  void commit() {
    std::vector<fs::path> files;
    for (const auto& e : fs::directory_iterator(tmpdir_)) files.push_back(e.path());
    std::stable_partition(files.begin(), files.end(), [&](const fs::path& p) { return p.filename() != target_.filename(); });
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

template <class TImage>
void write_image(TImage* img, const std::string& path, const std::vector<Format>& allowed, const char* what) {
  const Format f = detail::format_of(path);
  if (std::find(allowed.begin(), allowed.end(), f) == allowed.end()) {
    std::string list;
    for (Format a : allowed) list += (list.empty() ? "" : ", ") + detail::extension_of(a);
    throw Error(path + ": unsupported extension for " + what + " (supported: " + list + ")");
  }
  AtomicWrite aw(path);
  auto writer = itk::ImageFileWriter<TImage>::New();
  writer->SetImageIO(make_io(f));
  writer->SetFileName(aw.temp_path());
  writer->SetInput(img);
  // Single-file formats are compressed; detached ones (.nhdr, .mhd) keep raw data.
  writer->SetUseCompression(f == Format::NiftiGz || f == Format::Nrrd || f == Format::Mha);
  try {
    writer->Update();
  } catch (const itk::ExceptionObject& e) {
    throw Error(path + ": cannot write " + what + ": " + one_line(e));
  }
  aw.commit();
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
  try {
    if (fs::is_directory(st)) return read_dicom_dir(path, opt);
    if (!fs::is_regular_file(st)) throw Error(path + ": not a regular file or directory");
    if (!opt.series_uid.empty())
      throw Error(path + ": --series applies only to a DICOM series directory, not to a file");
    return read_file(path);
  } catch (const itk::ExceptionObject& e) {
    throw Error(path + ": " + one_line(e));
  } catch (const fs::filesystem_error& e) {
    throw Error(path + ": " + e.what());
  }
}

Volume read_volume(const std::string& path, const ReadOptions& opt) {
  return to_lps_order(read_volume_as_stored(path, opt));
}

Input load_input(const std::string& path, const InputOptions& opt) {
  ReadOptions ro;
  ro.series_uid = opt.series_uid;
  return prepare_input(read_volume_as_stored(path, ro), opt, path);
}

std::vector<DicomSeriesInfo> list_dicom_series(const std::string& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw Error(dir + ": not a directory");
  return scan_dicom_dir(dir).info;
}

void write_volume(const Volume& v, const std::string& path) {
  validate_volume(v, path);
  write_scalar(v.hu, v.dims, v.spacing, v.origin, v.direction, path);
}

void write_displacement_field(const Input& in, const Model& m, const std::vector<Vec3>& pos, const std::string& path) {
  const std::vector<float> u = displacement_on_input_grid(in, m, pos);
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

void write_deformed_volume(const Volume& target, const Model& m, const std::vector<Vec3>& pos,
                           const std::string& path) {
  validate_volume(target, path);
  const std::vector<float> hu = detail::resample_deformed(target, m, pos);
  write_scalar(hu, target.dims, target.spacing, target.origin, target.direction, path);
}

void write_deformed_volume(const Input& in, const Model& m, const std::vector<Vec3>& pos, const std::string& path) {
  detail::check_model_matches(in, m, path + ": deformed CT");
  write_deformed_volume(in.stored, m, pos, path);
}

void write_label_map(const Input& in, const Model& m, const std::string& path) {
  detail::check_model_matches(in, m, path + ": label map");
  if (static_cast<Index>(m.tissue.size()) != m.size())
    throw Error(path + ": label map: the model has " + std::to_string(m.tissue.size()) + " tissue labels for " +
                std::to_string(m.size()) + " elements");
  using LabelImage = itk::Image<unsigned char, 3>;
  const Grid& g = in.lattice_grid;
  auto img = make_image<LabelImage>(g.dims, g.spacing, g.origin, g.direction);
  img->Allocate();
  unsigned char* dst = img->GetBufferPointer();
  detail::for_each_lattice_voxel(g.dims, in.order, [&](std::int64_t l, std::int64_t s) { dst[s] = m.tissue[l]; });
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
    if (!out) throw Error(ctbl + ": cannot write the colour table");
  }
  aw.commit();
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
    r.geometry.dims = {int(size[0]), int(size[1]), int(size[2])};
    for (int a = 0; a < 3; ++a) {
      r.geometry.spacing[a] = img->GetSpacing()[a];
      r.geometry.origin[a] = img->GetOrigin()[a];
      for (int c = 0; c < 3; ++c) r.geometry.direction[a * 3 + c] = img->GetDirection()(a, c);
    }
    const std::size_t n = std::size_t(size[0]) * size[1] * size[2] * img->GetNumberOfComponentsPerPixel();
    r.data.assign(img->GetBufferPointer(), img->GetBufferPointer() + n);
  } catch (const itk::ExceptionObject& e) {
    throw Error(path + ": " + one_line(e));
  }
  return r;
}
}  // namespace detail

}  // namespace hpcm::io
