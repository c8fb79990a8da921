// Hostile parameter and scenario files (issue 15): a directory, /dev/zero, binary data and
// huge files are clear errors (bounded reads, no hang); keyframe offsets are bounded so that
// a scenario accepted by --check-scenario cannot overflow to a non-finite tool offset mid-run.
#include <gtest/gtest.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <future>
#include <fstream>

#include "hpcm/config.hpp"

namespace fs = std::filesystem;
namespace cfg = hpcm::config;

namespace {
std::string hostile_error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const hpcm::Error& e) {
    return e.what();
  }
  return "NO ERROR";
}
fs::path scratch(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("hpcm_hostile_cfg_" + name + "_" + std::to_string(getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}
}  // namespace

TEST(HostileConfigFiles, DirectoryIsNotAParameterFile) {
  const fs::path d = scratch("dir");
  EXPECT_NE(hostile_error_of([&] { cfg::load_params(d.string()); }).find("is a directory, not a parameter file"), std::string::npos);
  EXPECT_NE(hostile_error_of([&] { cfg::load_scenario(d.string()); }).find("is a directory, not a scenario file"), std::string::npos);
  fs::remove_all(d);
}

TEST(HostileConfigFiles, DevZeroIsRefusedAsNotARegularFile) {
  if (!fs::exists("/dev/zero")) GTEST_SKIP() << "no /dev/zero";
  const std::string msg = hostile_error_of([] { cfg::load_params("/dev/zero"); });
  EXPECT_NE(msg.find("/dev/zero: is not a regular file"), std::string::npos) << msg;
}

// Opening a FIFO blocks until a writer comes: it must be refused before it is opened.
TEST(HostileConfigFiles, FifoIsRefusedWithoutBlocking) {
  const fs::path d = scratch("fifo");
  const fs::path fifo = d / "params.toml";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  // Without the check the read blocks: after 5 s a writer opens and closes the FIFO to free it.
  const auto error_within_5s = [&](const std::function<void()>& load) {
    auto reading = std::async(std::launch::async, [&] { return hostile_error_of(load); });
    if (reading.wait_for(std::chrono::seconds(5)) == std::future_status::timeout) {
      ADD_FAILURE() << "blocked on a FIFO";
      ::close(::open(fifo.c_str(), O_WRONLY));
    }
    return reading.get();
  };
  const std::string pmsg = error_within_5s([&] { cfg::load_params(fifo.string()); });
  EXPECT_NE(pmsg.find(fifo.string() + ": is not a regular file"), std::string::npos) << pmsg;
  const std::string smsg = error_within_5s([&] { cfg::load_scenario(fifo.string()); });
  EXPECT_NE(smsg.find("not a scenario file"), std::string::npos) << smsg;
  fs::remove_all(d);
}

TEST(HostileConfigFiles, BinaryAndOversizedFilesAreRefused) {
  const fs::path d = scratch("bin");
  {
    std::ofstream f(d / "nul.toml", std::ios::binary);
    f << "[dynamics]\nalpha = 0.5\n" << '\0' << "beta = 1.0\n";
  }
  EXPECT_NE(hostile_error_of([&] { cfg::load_params((d / "nul.toml").string()); }).find("NUL bytes"), std::string::npos);
  {
    std::ofstream f(d / "big.toml", std::ios::binary);
    const std::string comment = "# " + std::string(1000, 'x') + "\n";
    for (int i = 0; i < 5000; ++i) f << comment;  // 5 MB of comments
  }
  EXPECT_NE(hostile_error_of([&] { cfg::load_params((d / "big.toml").string()); }).find("larger than 4 MiB"), std::string::npos);
  EXPECT_NE(hostile_error_of([&] { cfg::load_params((d / "missing.toml").string()); }).find("missing.toml: cannot open"),
            std::string::npos);
  fs::remove_all(d);
}

TEST(HostileConfigFiles, KeyframeOffsetsAreBoundedSoTheyStayFinite) {
  // Two finite offsets near FLT_MAX would make the interpolated tool offset infinite.
  const std::string msg = hostile_error_of([] {
    cfg::parse_scenario("[scenario]\nframes = 30\n[[grab]]\ncentre = [4, 4, 4]\nrelease = 20\n"
                        "keyframes = [[5, 3e38, 0, 0], [10, -3e38, 0, 0]]\n",
                        "huge.toml");
  });
  EXPECT_NE(msg.find("huge.toml: grab[0].keyframes[0][1] (dx) = "), std::string::npos) << msg;
  EXPECT_NE(msg.find("out of range [-10000, 10000]"), std::string::npos) << msg;
  EXPECT_NE(msg.find("(line 6)"), std::string::npos) << msg;
  EXPECT_NO_THROW(cfg::parse_scenario("[scenario]\nframes = 30\n[[grab]]\nrelease = 20\nkeyframes = [[5, 0, -10000, 0]]\n", "ok.toml"));
}
