// The C ABI over board_common (firmware/sim/board_common/ja_sim_board.h), its source compiled
// into this test with the sanitizers: the common options and their usage, the rig on the virtual
// devices, the settings file (a new, empty, existing and wrong-size file, the temporary one, the
// write-back), the sensor-fault schedule, the pty line (serial faults, the host's bytes, the wait)
// and the cable cut between frames (after the delimiter, on an idle line, the reconnect), and
// every call on NULL.
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "app/app_config.hpp"
#include "check.hpp"
#include "platform/posix/rig_toml.hpp"
#include "protocol/messages.hpp"
#include "sim/board_common/ja_sim_board.h"

namespace {

constexpr uint64_t kMs = 1000000;  // ns

// Links a and b with two ADXL345 each at 0x53 behind the TCA9548A, channels 0..3.
const char kRig[] =
    "name = \"ctest-board\"\nsample_rate_hz = 250\n"
    "[links.a]\njoint = [0.3, 0.0]\n"
    "[[links.a.sensors]]\nmodel = \"adxl345\"\nposition = [0.2525, 0.0]\nmux_channel = 0\n"
    "address = 0x53\nrange_g = 2\n"
    "[[links.a.sensors]]\nmodel = \"adxl345\"\nposition = [0.025, 0.0]\nmux_channel = 1\n"
    "address = 0x53\nrange_g = 2\n"
    "[links.b]\njoint = [0.0, 0.0]\n"
    "[[links.b.sensors]]\nmodel = \"adxl345\"\nposition = [0.0475, 0.0]\nmux_channel = 2\n"
    "address = 0x53\nrange_g = 2\n"
    "[[links.b.sensors]]\nmodel = \"adxl345\"\nposition = [0.275, 0.0]\nmux_channel = 3\n"
    "address = 0x53\nrange_g = 2\n";

std::string g_dir;  // this run's temporary directory

void WriteFile(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

std::string ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

bool Exists(const std::string& path) {
  struct stat st;
  return lstat(path.c_str(), &st) == 0;
}

void SetUp() {
  const char* base = getenv("TMPDIR");
  std::string tmpl = std::string(base && *base ? base : "/tmp") + "/test_sim_board-XXXXXX";
  std::vector<char> buf(tmpl.begin(), tmpl.end());
  buf.push_back('\0');
  CHECK(mkdtemp(buf.data()) != nullptr);
  g_dir = buf.data();
  WriteFile(g_dir + "/rig.toml", kRig);
  std::string csv = "t";
  for (const char* s : {"a.0", "a.1", "b.0", "b.1"}) {
    for (const char* ax : {"x", "y", "z"}) csv += std::string(",") + s + "." + ax;
  }
  csv += "\n";
  for (int k = 0; k < 100; ++k) {
    csv += std::to_string(k * 0.01);
    for (int s = 0; s < 4; ++s) csv += ",0.0,9.81,0.0";
    csv += "\n";
  }
  WriteFile(g_dir + "/motion.csv", csv);
}

void TearDown() {
  const std::string cmd = "rm -rf '" + g_dir + "'";
  CHECK(system(cmd.c_str()) == 0);
}

/// What the program writes to one of its streams (fd 1 or 2) while it lives.
class Capture {
 public:
  explicit Capture(int fd) : fd_(fd), path_(g_dir + "/capture" + std::to_string(fd)) {
    fflush(fd == 1 ? stdout : stderr);
    saved_ = dup(fd);
    const int f = open(path_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    dup2(f, fd);
    close(f);
  }
  ~Capture() { Text(); }
  /// Everything so far; the stream is restored at the first call.
  std::string Text() {
    if (saved_ >= 0) {
      fflush(fd_ == 1 ? stdout : stderr);
      dup2(saved_, fd_);
      close(saved_);
      saved_ = -1;
      text_ = ReadFile(path_);
    }
    return text_;
  }

 private:
  int fd_, saved_ = -1;
  std::string path_, text_;
};

bool Contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

/// ja_sim_board_open on the rig and motion plus `extra`, under argv[0] "ja_test_board".
ja_sim_board* Open(const std::vector<std::string>& extra, const char* usage = nullptr) {
  std::vector<std::string> args = {"/some/dir/ja_test_board", "--rig", g_dir + "/rig.toml",
                                   "--motion", g_dir + "/motion.csv"};
  args.insert(args.end(), extra.begin(), extra.end());
  std::vector<const char*> argv;
  for (const std::string& a : args) argv.push_back(a.c_str());
  return ja_sim_board_open(static_cast<int>(argv.size()), argv.data(), usage);
}

/// ja_sim_board_open on exactly `args` (argv[0] first); stderr captured into *err.
ja_sim_board* OpenRaw(const std::vector<std::string>& args, std::string* err) {
  std::vector<const char*> argv;
  for (const std::string& a : args) argv.push_back(a.c_str());
  Capture capture(2);
  ja_sim_board* b =
      ja_sim_board_open(static_cast<int>(argv.size()), argv.data(), "  [--own-option X]\n");
  *err = capture.Text();
  return b;
}

/// The ADXL345's DEVID behind mux channel `channel`: the ja_sim result of the read.
int ReadDevid(ja_sim* sim, uint8_t channel, uint8_t* devid) {
  const uint8_t mask = static_cast<uint8_t>(1u << channel);
  if (ja_sim_i2c_write(sim, 0x70, &mask, 1) != JA_SIM_OK) return -1;
  const uint8_t reg = 0x00;
  return ja_sim_i2c_write_read(sim, 0x53, &reg, 1, devid, 1);
}

void TestNullSafety() {
  uint8_t buf[4] = {0};
  ja_sim_board_line_counters c;
  CHECK_EQ(ja_sim_board_abi_version(), JA_SIM_BOARD_ABI_VERSION);
  CHECK(ja_sim_board_open(0, nullptr, nullptr) == nullptr);
  CHECK(std::strlen(ja_sim_board_last_error(nullptr)) > 0);
  const char* null_arg[] = {"ja_test_board", nullptr};
  CHECK(ja_sim_board_open(2, null_arg, nullptr) == nullptr);
  ja_sim_board_close(nullptr);
  CHECK(ja_sim_board_sim(nullptr) == nullptr);
  CHECK_EQ(ja_sim_board_baud(nullptr), 0u);
  CHECK_EQ(ja_sim_board_fast(nullptr), 0);
  CHECK_EQ(ja_sim_board_loop_motion(nullptr), 0);
  CHECK_EQ(ja_sim_board_cold_start(nullptr), 0);
  CHECK_EQ(ja_sim_board_disconnect_after_s(nullptr), -1.0);
  CHECK_EQ(ja_sim_board_reconnect_after_s(nullptr), -1.0);
  CHECK_EQ(std::string(ja_sim_board_link(nullptr)), "");
  CHECK_EQ(ja_sim_board_rate_hz(nullptr), 0u);
  CHECK_EQ(ja_sim_board_settings_open(nullptr, buf, sizeof buf, 0), JA_SIM_EINVAL);
  CHECK_EQ(ja_sim_board_settings_write(nullptr, buf, sizeof buf), JA_SIM_EINVAL);
  CHECK_EQ(std::string(ja_sim_board_settings_path(nullptr)), "");
  CHECK_EQ(ja_sim_board_apply_faults(nullptr, 0), JA_SIM_EINVAL);
  CHECK_EQ(ja_sim_board_line_open(nullptr), JA_SIM_EINVAL);
  CHECK_EQ(ja_sim_board_line_put(nullptr, 0, 0), JA_SIM_EINVAL);
  CHECK_EQ(ja_sim_board_line_take(nullptr, buf, sizeof buf), JA_SIM_EINVAL);
  CHECK_EQ(ja_sim_board_line_flush(nullptr), JA_SIM_EINVAL);
  CHECK_EQ(ja_sim_board_line_waiting(nullptr), 0u);
  CHECK_EQ(ja_sim_board_line_wait(nullptr, 0), JA_SIM_EINVAL);
  CHECK_EQ(ja_sim_board_line_service(nullptr, 0), JA_SIM_EINVAL);
  CHECK_EQ(ja_sim_board_line_connected(nullptr), 0);
  CHECK_EQ(std::string(ja_sim_board_line_path(nullptr)), "");
  CHECK_EQ(ja_sim_board_line_get_counters(nullptr, &c, sizeof c), JA_SIM_EINVAL);

  // A board: NULL buffers and wrong sizes fail with a reason, not a crash.
  ja_sim_board* b = Open({});
  CHECK(b != nullptr);
  CHECK_EQ(ja_sim_board_settings_open(b, nullptr, 4096, 0), JA_SIM_EINVAL);
  CHECK(Contains(ja_sim_board_last_error(b), "no image buffer"));
  CHECK_EQ(ja_sim_board_settings_open(b, buf, 0, 0), JA_SIM_EINVAL);
  CHECK_EQ(ja_sim_board_settings_write(b, buf, sizeof buf), JA_SIM_EINVAL);
  CHECK(Contains(ja_sim_board_last_error(b), "not open"));
  CHECK_EQ(ja_sim_board_line_take(b, nullptr, 4), JA_SIM_EINVAL);
  CHECK_EQ(ja_sim_board_line_get_counters(b, nullptr, sizeof c), JA_SIM_EINVAL);
  CHECK_EQ(ja_sim_board_line_get_counters(b, &c, sizeof c - 8), JA_SIM_EINVAL);
  // No line yet: a byte goes nowhere (counted), the cable has nothing to do.
  CHECK_EQ(ja_sim_board_line_put(b, 0x41, 0), 0);
  CHECK_EQ(ja_sim_board_line_take(b, buf, sizeof buf), 0);
  CHECK_EQ(ja_sim_board_line_service(b, 10 * kMs), 0);
  CHECK_EQ(ja_sim_board_line_connected(b), 0);
  CHECK_EQ(ja_sim_board_line_get_counters(b, &c, sizeof c), JA_SIM_OK);
  CHECK_EQ(c.tx_bytes, 1u);
  ja_sim_board_close(b);
}

void TestOptions() {
  ja_sim_board* b = Open({});
  CHECK(b != nullptr);
  CHECK_EQ(std::string(ja_sim_board_last_error(b)), "");
  ja_sim* sim = ja_sim_board_sim(b);
  CHECK(sim != nullptr);
  CHECK_EQ(ja_sim_device_count(sim), 5);  // the mux and four ADXL345
  CHECK(ja_sim_find_device(sim, "b.1") >= 0);
  uint8_t devid = 0;
  CHECK_EQ(ReadDevid(sim, 3, &devid), JA_SIM_OK);
  CHECK_EQ(devid, 0xE5);
  CHECK_EQ(ja_sim_board_baud(b), 0u);
  CHECK_EQ(ja_sim_board_fast(b), 0);
  CHECK_EQ(ja_sim_board_loop_motion(b), 0);
  CHECK_EQ(ja_sim_board_cold_start(b), 0);
  CHECK_EQ(ja_sim_board_disconnect_after_s(b), -1.0);
  CHECK_EQ(ja_sim_board_reconnect_after_s(b), -1.0);
  CHECK_EQ(std::string(ja_sim_board_link(b)), "");
  CHECK_EQ(ja_sim_board_rate_hz(b), 250u);
  ja_sim_board_close(b);

  b = Open({"--baud", "115200", "--fast", "--loop-motion", "--cold-start", "--disconnect-after",
            "1.5", "--reconnect-after", "0.25", "--link", g_dir + "/opt-link"});
  CHECK(b != nullptr);
  CHECK_EQ(ja_sim_board_baud(b), 115200u);
  CHECK_EQ(ja_sim_board_fast(b), 1);
  CHECK_EQ(ja_sim_board_loop_motion(b), 1);
  CHECK_EQ(ja_sim_board_cold_start(b), 1);
  CHECK_EQ(ja_sim_board_disconnect_after_s(b), 1.5);
  CHECK_EQ(ja_sim_board_reconnect_after_s(b), 0.25);
  CHECK_EQ(std::string(ja_sim_board_link(b)), g_dir + "/opt-link");
  ja_sim_board_close(b);

  // An unknown argument: the message, the common usage and the board's own, on stderr; NULL.
  std::string err;
  const std::string rig = g_dir + "/rig.toml", motion = g_dir + "/motion.csv";
  b = OpenRaw({"ja_test_board", "--rig", rig, "--motion", motion, "--bogus"}, &err);
  CHECK(b == nullptr);
  CHECK(Contains(err, "ja_test_board: unknown argument --bogus"));
  CHECK(Contains(err, "usage: ja_test_board --rig RIG.toml --motion DATA.csv"));
  CHECK(Contains(err, "  [--own-option X]\n"));
  CHECK(Contains(err, "--fault SENSOR:KIND"));
  CHECK(Contains(ja_sim_board_last_error(nullptr), "unknown argument --bogus"));
  // A malformed value, a missing one, no motion: the usage.
  for (const std::vector<std::string>& args :
       {std::vector<std::string>{"b", "--rig", rig, "--motion", motion, "--baud", "12"},
        std::vector<std::string>{"b", "--rig", rig, "--motion"},
        std::vector<std::string>{"b", "--rig", rig}}) {
    b = OpenRaw(args, &err);
    CHECK(b == nullptr);
    CHECK(Contains(err, "usage: b --rig"));
    CHECK(std::strlen(ja_sim_board_last_error(nullptr)) > 0);
  }
  b = OpenRaw({"b", "--rig", rig, "--motion", motion, "--fault", "a.0:melt@1"}, &err);
  CHECK(b == nullptr);
  CHECK(Contains(err, "b: --fault a.0:melt@1: unknown fault kind 'melt'"));
  // What the rig cannot do: its reason, no usage.
  b = OpenRaw({"b", "--rig", rig, "--motion", motion, "--fault", "c.0:nack@1"}, &err);
  CHECK(b == nullptr);
  CHECK(Contains(err, "b: --fault: the rig has no sensor 'c.0'"));
  CHECK(!Contains(err, "usage:"));
  CHECK(Contains(ja_sim_board_last_error(nullptr), "the rig has no sensor 'c.0'"));
  b = OpenRaw({"b", "--rig", g_dir + "/absent.toml", "--motion", motion}, &err);
  CHECK(b == nullptr);
  CHECK(Contains(err, "b: cannot read the rig " + g_dir + "/absent.toml"));
  // A successful open clears the thread's open error.
  b = Open({});
  CHECK_EQ(std::string(ja_sim_board_last_error(nullptr)), "");
  ja_sim_board_close(b);
}

/// The application's EEPROM interface over a byte vector.
class VectorEeprom final : public ja::app::Eeprom {
 public:
  explicit VectorEeprom(std::vector<uint8_t>& bytes) : bytes_(bytes) {}
  uint16_t Size() override { return static_cast<uint16_t>(bytes_.size()); }
  uint8_t Read(uint16_t addr) override { return bytes_[addr]; }
  void Write(uint16_t addr, uint8_t value) override { bytes_[addr] = value; }

 private:
  std::vector<uint8_t>& bytes_;
};

void TestSettings() {
  // The image of a new store: erased, then the rig's configuration as SaveConfig writes it.
  ja::app::Config rig_cfg{};
  std::string spec, error;
  CHECK(ja::posix::RigToConfig(kRig, &rig_cfg, &spec, &error));
  std::vector<uint8_t> expected(4096, 0xFF);
  VectorEeprom expected_store(expected);
  CHECK(ja::app::SaveConfig(expected_store, rig_cfg));

  // A new file (absent): that image, in the file too; the app loads the rig from it.
  const std::string path = g_dir + "/settings.bin";
  ja_sim_board* b = Open({"--eeprom", path});
  std::vector<uint8_t> image(4096, 0);
  CHECK_EQ(ja_sim_board_settings_open(b, image.data(), image.size(), 0), JA_SIM_OK);
  CHECK_EQ(std::string(ja_sim_board_settings_path(b)), path);
  CHECK(image == expected);
  CHECK(ReadFile(path) == std::string(expected.begin(), expected.end()));
  ja::app::Config loaded{};
  VectorEeprom loaded_store(image);
  CHECK_EQ(ja::app::LoadConfig(loaded_store, loaded),
           static_cast<uint8_t>(ja::proto::EepromState::kOk));
  CHECK_EQ(loaded.rate_hz, 250);
  CHECK_EQ(loaded.sensor_count, 4);
  // Once per board.
  CHECK_EQ(ja_sim_board_settings_open(b, image.data(), image.size(), 0), JA_SIM_EINVAL);
  // The firmware changes bytes: only those are written back.
  image[10] ^= 0x01, image[11] ^= 0x02, image[4000] = 0x12, image[4095] = 0x34;
  CHECK_EQ(ja_sim_board_settings_write(b, image.data(), image.size()), 4);
  CHECK_EQ(ja_sim_board_settings_write(b, image.data(), image.size()), 0);
  CHECK(ReadFile(path) == std::string(image.begin(), image.end()));
  CHECK_EQ(ja_sim_board_settings_write(b, image.data(), 1024), JA_SIM_EINVAL);
  CHECK(Contains(ja_sim_board_last_error(b), path));
  ja_sim_board_close(b);
  CHECK(Exists(path));  // --eeprom stays

  // An existing file of the size is used as it is (not rewritten with the rig).
  b = Open({"--eeprom", path});
  std::vector<uint8_t> again(4096, 0);
  CHECK_EQ(ja_sim_board_settings_open(b, again.data(), again.size(), 0), JA_SIM_OK);
  CHECK(again == image);
  ja_sim_board_close(b);

  // An empty file is a new one; with the erased flag it stays erased.
  const std::string empty = g_dir + "/empty.bin";
  WriteFile(empty, "");
  b = Open({"--eeprom", empty});
  CHECK_EQ(ja_sim_board_settings_open(b, again.data(), again.size(), 0), JA_SIM_OK);
  CHECK(again == expected);
  ja_sim_board_close(b);
  const std::string erased = g_dir + "/erased.bin";
  b = Open({"--eeprom", erased});
  CHECK_EQ(ja_sim_board_settings_open(b, again.data(), again.size(), JA_SIM_BOARD_SETTINGS_ERASED),
           JA_SIM_OK);
  CHECK(again == std::vector<uint8_t>(4096, 0xFF));
  CHECK(ReadFile(erased) == std::string(4096, '\xFF'));
  ja_sim_board_close(b);

  // A store of another size: a new one of 1024 bytes holds the rig too; the 4 KB file is not
  // one of 1024 bytes, nor is a 100-byte file one of 4096: an error naming the file, which is
  // left as it was.
  const std::string small = g_dir + "/small.bin";
  b = Open({"--eeprom", small});
  std::vector<uint8_t> image_1k(1024, 0);
  CHECK_EQ(ja_sim_board_settings_open(b, image_1k.data(), image_1k.size(), 0), JA_SIM_OK);
  CHECK(
      std::equal(image_1k.begin(), image_1k.begin() + ja::app::kEepromImageSize, expected.begin()));
  CHECK_EQ(ReadFile(small).size(), 1024u);
  ja_sim_board_close(b);
  b = Open({"--eeprom", path});
  CHECK_EQ(ja_sim_board_settings_open(b, image_1k.data(), image_1k.size(), 0), JA_SIM_EINVAL);
  CHECK(Contains(ja_sim_board_last_error(b), path + " is not an EEPROM image of this board"));
  ja_sim_board_close(b);
  CHECK(ReadFile(path) == std::string(image.begin(), image.end()));
  const std::string odd = g_dir + "/odd.bin";
  WriteFile(odd, std::string(100, 'x'));
  b = Open({"--eeprom", odd});
  CHECK_EQ(ja_sim_board_settings_open(b, again.data(), again.size(), 0), JA_SIM_EINVAL);
  CHECK(Contains(ja_sim_board_last_error(b), odd + " is not an EEPROM image of this board (100 "
                                                   "bytes, an image has 4096"));
  ja_sim_board_close(b);
  CHECK(ReadFile(odd) == std::string(100, 'x'));
  // Too small for the configuration; beyond the application's addresses.
  b = Open({"--eeprom", g_dir + "/tiny.bin"});
  std::vector<uint8_t> tiny(64, 0);
  CHECK_EQ(ja_sim_board_settings_open(b, tiny.data(), tiny.size(), 0), JA_SIM_EINVAL);
  CHECK(Contains(ja_sim_board_last_error(b), "cannot write the rig's configuration"));
  ja_sim_board_close(b);
  b = Open({"--eeprom", g_dir + "/huge.bin"});
  std::vector<uint8_t> huge(65536, 0);
  CHECK_EQ(ja_sim_board_settings_open(b, huge.data(), huge.size(), 0), JA_SIM_EINVAL);
  CHECK(!Exists(g_dir + "/huge.bin"));
  ja_sim_board_close(b);

  // No --eeprom: a temporary file with the rig's image, gone with the board.
  setenv("TMPDIR", g_dir.c_str(), 1);
  b = Open({});
  CHECK_EQ(ja_sim_board_settings_open(b, again.data(), again.size(), 0), JA_SIM_OK);
  const std::string tmp = ja_sim_board_settings_path(b);
  CHECK(Contains(tmp, g_dir + "/ja_test_board-settings-"));
  CHECK(again == expected);
  CHECK(ReadFile(tmp) == std::string(expected.begin(), expected.end()));
  ja_sim_board_close(b);
  CHECK(!Exists(tmp));
  CHECK(!Exists(tmp.substr(0, tmp.rfind('/'))));
  unsetenv("TMPDIR");
}

void TestSensorFaults() {
  std::string err;
  Capture capture(2);
  ja_sim_board* b = Open({"--fault", "a.1:nack@0.5-1.0", "--fault", "mux:nack@2"});
  ja_sim* sim = ja_sim_board_sim(b);
  uint8_t devid = 0;
  CHECK_EQ(ja_sim_board_apply_faults(b, 0), JA_SIM_OK);
  CHECK_EQ(ReadDevid(sim, 1, &devid), JA_SIM_OK);
  CHECK_EQ(ja_sim_board_apply_faults(b, 500 * kMs - 1), JA_SIM_OK);
  CHECK_EQ(ReadDevid(sim, 1, &devid), JA_SIM_OK);
  CHECK_EQ(ja_sim_board_apply_faults(b, 500 * kMs), JA_SIM_OK);
  CHECK_EQ(ReadDevid(sim, 1, &devid), JA_SIM_ADDRESS_NACK);
  CHECK_EQ(ReadDevid(sim, 0, &devid), JA_SIM_OK);  // a.0 is not at fault
  CHECK_EQ(ja_sim_board_apply_faults(b, 1000 * kMs), JA_SIM_OK);
  CHECK_EQ(ReadDevid(sim, 1, &devid), JA_SIM_OK);
  CHECK_EQ(ja_sim_board_apply_faults(b, 2000 * kMs), JA_SIM_OK);
  CHECK_EQ(ReadDevid(sim, 1, &devid), -1);  // the mux refuses its address
  ja_sim_board_close(b);
  err = capture.Text();
  CHECK(Contains(err, "ja_test_board: 0.500 s: fault 1 on a.1"));
  CHECK(Contains(err, "ja_test_board: 1.000 s: fault 1 off a.1"));
  CHECK(Contains(err, "ja_test_board: 2.000 s: fault 1 on mux"));
}

/// The host's end of the board's pty (non-blocking).
int OpenHost(ja_sim_board* b) {
  return open(ja_sim_board_line_path(b), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
}

/// What the host reads within `ms` (until `want` bytes came).
std::vector<uint8_t> HostRead(int fd, size_t want, int ms = 1000) {
  std::vector<uint8_t> got;
  for (int i = 0; i < ms && got.size() < want; ++i) {
    uint8_t buf[256];
    const ssize_t n = read(fd, buf, sizeof buf);
    if (n > 0) {
      got.insert(got.end(), buf, buf + n);
    } else {
      usleep(1000);
    }
  }
  return got;
}

/// Bytes the board takes from the host within `ms` (until `want` came).
std::vector<uint8_t> BoardTake(ja_sim_board* b, size_t want, size_t cap, int ms = 1000) {
  std::vector<uint8_t> got;
  for (int i = 0; i < ms && got.size() < want; ++i) {
    uint8_t buf[64];
    const int n = ja_sim_board_line_take(b, buf, std::min(cap, sizeof buf));
    CHECK(n >= 0);
    if (n > 0) {
      got.insert(got.end(), buf, buf + n);
    } else {
      usleep(1000);
    }
  }
  return got;
}

uint64_t WallNs() {
  timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<uint64_t>(ts.tv_sec) * 1000000000ull + static_cast<uint64_t>(ts.tv_nsec);
}

void TestLineFaults() {
  const std::string link = g_dir + "/line-link";
  Capture out(1);
  ja_sim_board* b = Open({"--drop-every", "3", "--corrupt-every", "2", "--link", link});
  CHECK_EQ(ja_sim_board_line_open(b), JA_SIM_OK);
  CHECK_EQ(ja_sim_board_line_open(b), JA_SIM_EINVAL);  // open already
  const std::string path = ja_sim_board_line_path(b);
  CHECK(Contains(path, "/dev/pts/"));
  CHECK_EQ(ja_sim_board_line_connected(b), 1);
  char target[128] = {0};
  CHECK(readlink(link.c_str(), target, sizeof target - 1) > 0);
  CHECK_EQ(std::string(target), path);
  const int host = OpenHost(b);
  CHECK(host >= 0);

  // Byte n (from 1): dropped when 3 divides n, else XORed with 0x5A when 2 does.
  std::vector<uint8_t> expected;
  for (uint8_t n = 1; n <= 12; ++n) {
    const int put = ja_sim_board_line_put(b, n, n * 20000ull);
    CHECK_EQ(put, n % 3 == 0 ? 0 : 1);
    if (n % 3 != 0) expected.push_back(n % 2 == 0 ? static_cast<uint8_t>(n ^ 0x5A) : n);
  }
  CHECK_EQ(ja_sim_board_line_waiting(b), expected.size());
  CHECK_EQ(ja_sim_board_line_flush(b), JA_SIM_OK);
  CHECK_EQ(ja_sim_board_line_waiting(b), 0u);
  CHECK(HostRead(host, expected.size()) == expected);

  // The host's bytes, in order, as many as the board asks for at a time.
  const uint8_t hello[] = {'h', 'e', 'l', 'l', 'o'};
  CHECK_EQ(write(host, hello, sizeof hello), static_cast<ssize_t>(sizeof hello));
  CHECK(BoardTake(b, 2, 2) == std::vector<uint8_t>({'h', 'e'}));
  CHECK(BoardTake(b, 3, 1) == std::vector<uint8_t>({'l', 'l', 'o'}));
  uint8_t none[4];
  CHECK_EQ(ja_sim_board_line_take(b, none, sizeof none), 0);

  // The wait ends early when the host sends a byte; it sleeps its time otherwise.
  uint64_t t0 = WallNs();
  CHECK_EQ(ja_sim_board_line_wait(b, 30 * kMs), JA_SIM_OK);
  CHECK(WallNs() - t0 >= 25 * kMs);
  CHECK_EQ(write(host, "x", 1), 1);
  t0 = WallNs();
  CHECK_EQ(ja_sim_board_line_wait(b, 2000 * kMs), JA_SIM_OK);
  CHECK(WallNs() - t0 < 1000 * kMs);
  CHECK(BoardTake(b, 1, 1) == std::vector<uint8_t>({'x'}));

  ja_sim_board_line_counters c;
  CHECK_EQ(ja_sim_board_line_get_counters(b, &c, sizeof c), JA_SIM_OK);
  CHECK_EQ(c.tx_bytes, 12u);
  CHECK_EQ(c.rx_bytes, 6u);
  CHECK_EQ(c.dropped, 4u);    // 3, 6, 9, 12
  CHECK_EQ(c.corrupted, 4u);  // 2, 4, 8, 10
  CHECK_EQ(c.bridge_dropped, 0u);
  CHECK_EQ(c.disconnects, 0u);
  ja_sim_board_close(b);
  close(host);
  CHECK(!Exists(link));  // the link goes with the pty
  CHECK_EQ(out.Text(), "PTY " + path + "\n");
}

void TestBridgeDrop() {
  // Nobody reads: the wire keeps 2 x JA_SIM_BOARD_WIRE_MAX bytes, the rest is dropped and counted.
  Capture out(1);
  ja_sim_board* b = Open({});
  CHECK_EQ(ja_sim_board_line_open(b), JA_SIM_OK);
  for (uint32_t i = 0; i < 2 * JA_SIM_BOARD_WIRE_MAX + 10; ++i)
    ja_sim_board_line_put(b, 0x55, i * 20000ull);
  CHECK_EQ(ja_sim_board_line_waiting(b), 2 * JA_SIM_BOARD_WIRE_MAX);
  ja_sim_board_line_counters c;
  CHECK_EQ(ja_sim_board_line_get_counters(b, &c, sizeof c), JA_SIM_OK);
  CHECK_EQ(c.bridge_dropped, 10u);
  ja_sim_board_close(b);
}

void TestCutBetweenFrames() {
  const std::string link = g_dir + "/cut-link";
  Capture out(1);
  ja_sim_board* b = Open({"--disconnect-after", "1", "--reconnect-after", "0.05", "--link", link});
  CHECK_EQ(ja_sim_board_line_open(b), JA_SIM_OK);
  const std::string first = ja_sim_board_line_path(b);
  const int host = OpenHost(b);
  CHECK(host >= 0);
  // A whole frame before S: nothing happens.
  uint64_t t = 900 * kMs;
  for (uint8_t v : {1, 2, 3, 0}) CHECK_EQ(ja_sim_board_line_put(b, v, t += 20000), 1);
  CHECK_EQ(ja_sim_board_line_service(b, t), 0);
  // S passes in the middle of the next frame: the cut waits for its delimiter, bytes after it
  // no longer reach the wire.
  t = 1000 * kMs;
  for (uint8_t v : {5, 6}) CHECK_EQ(ja_sim_board_line_put(b, v, t += 20000), 1);
  CHECK_EQ(ja_sim_board_line_service(b, t + 1000), 0);
  CHECK_EQ(ja_sim_board_line_connected(b), 1);
  for (uint8_t v : {7, 0}) CHECK_EQ(ja_sim_board_line_put(b, v, t += 20000), 1);
  for (uint8_t v : {9, 10, 0}) CHECK_EQ(ja_sim_board_line_put(b, v, t += 20000), 0);
  CHECK_EQ(ja_sim_board_line_flush(b), JA_SIM_OK);
  CHECK(HostRead(host, 8) == std::vector<uint8_t>({1, 2, 3, 0, 5, 6, 7, 0}));
  // A byte the host sent that the board has not taken is lost with the cable.
  CHECK_EQ(write(host, "ab", 2), 2);
  CHECK(BoardTake(b, 1, 1) == std::vector<uint8_t>({'a'}));
  const uint64_t pull0 = WallNs();
  CHECK_EQ(ja_sim_board_line_service(b, t), JA_SIM_BOARD_LINE_PULLED);
  const uint64_t pull_ns = WallNs() - pull0;
  CHECK(pull_ns >= 100 * kMs && pull_ns < 2100 * kMs);  // the host had read everything
  CHECK_EQ(ja_sim_board_line_connected(b), 0);
  CHECK_EQ(std::string(ja_sim_board_line_path(b)), "");
  CHECK(!Exists(link));
  CHECK_EQ(ja_sim_board_line_put(b, 0x11, t += 20000), 0);
  uint8_t buf[4];
  CHECK_EQ(ja_sim_board_line_take(b, buf, sizeof buf), 0);
  close(host);
  // R wall seconds later: a new pty, announced.
  int r = 0;
  for (int i = 0; i < 2000 && r == 0; ++i) {
    r = ja_sim_board_line_service(b, t += kMs);
    if (r == 0) usleep(1000);
  }
  CHECK_EQ(r, JA_SIM_BOARD_LINE_RECONNECTED);
  CHECK(WallNs() - pull0 >= pull_ns + 50 * kMs);
  CHECK_EQ(ja_sim_board_line_connected(b), 1);
  const std::string second = ja_sim_board_line_path(b);
  char target[128] = {0};
  CHECK(readlink(link.c_str(), target, sizeof target - 1) > 0);
  CHECK_EQ(std::string(target), second);
  // The line works again; the cable comes out once only.
  const int host2 = OpenHost(b);
  CHECK(host2 >= 0);
  for (uint8_t v : {0x21, 0x22, 0}) CHECK_EQ(ja_sim_board_line_put(b, v, t += 20000), 1);
  CHECK_EQ(ja_sim_board_line_service(b, t += 10 * kMs), 0);
  ja_sim_board_line_flush(b);
  CHECK(HostRead(host2, 3) == std::vector<uint8_t>({0x21, 0x22, 0}));
  CHECK_EQ(ja_sim_board_line_take(b, buf, sizeof buf), 0);
  ja_sim_board_line_counters c;
  CHECK_EQ(ja_sim_board_line_get_counters(b, &c, sizeof c), JA_SIM_OK);
  CHECK_EQ(c.disconnects, 1u);
  CHECK_EQ(c.rx_bytes, 1u);
  ja_sim_board_close(b);
  close(host2);
  CHECK_EQ(out.Text(), "PTY " + first + "\nDISCONNECTED\nPTY " + second + "\n");
}

void TestCutIdleLine() {
  // Nothing sent for 1 ms simulated when S passes: the line is between frames, the cable comes
  // out at once; without --reconnect-after it stays out.
  Capture out(1);
  ja_sim_board* b = Open({"--disconnect-after", "0.5"});
  CHECK_EQ(ja_sim_board_line_open(b), JA_SIM_OK);
  CHECK_EQ(ja_sim_board_line_put(b, 0x42, 100 * kMs), 1);
  ja_sim_board_line_flush(b);
  const int host = OpenHost(b);
  CHECK(HostRead(host, 1) == std::vector<uint8_t>({0x42}));
  CHECK_EQ(ja_sim_board_line_service(b, 499 * kMs), 0);
  CHECK_EQ(ja_sim_board_line_service(b, 500 * kMs), JA_SIM_BOARD_LINE_PULLED);
  CHECK_EQ(ja_sim_board_line_connected(b), 0);
  usleep(20000);
  CHECK_EQ(ja_sim_board_line_service(b, 600 * kMs), 0);
  CHECK_EQ(ja_sim_board_line_connected(b), 0);
  close(host);
  ja_sim_board_close(b);
  CHECK(Contains(out.Text(), "\nDISCONNECTED\n"));

  // Bytes within the last 1 ms: the cut waits for the end of that frame.
  Capture out2(1);
  b = Open({"--disconnect-after", "0.5"});
  CHECK_EQ(ja_sim_board_line_open(b), JA_SIM_OK);
  CHECK_EQ(ja_sim_board_line_put(b, 0x42, 499500000ull), 1);
  ja_sim_board_line_flush(b);
  const int host2 = OpenHost(b);
  CHECK(HostRead(host2, 1) == std::vector<uint8_t>({0x42}));
  CHECK_EQ(ja_sim_board_line_service(b, 500 * kMs), 0);
  CHECK_EQ(ja_sim_board_line_service(b, 500400000ull), 0);  // 0.9 ms idle
  CHECK_EQ(ja_sim_board_line_service(b, 500500000ull), JA_SIM_BOARD_LINE_PULLED);
  close(host2);
  ja_sim_board_close(b);
  CHECK(Contains(out2.Text(), "\nDISCONNECTED\n"));
}

}  // namespace

int main() {
  SetUp();
  TestNullSafety();
  TestOptions();
  TestSettings();
  TestSensorFaults();
  TestLineFaults();
  TestBridgeDrop();
  TestCutBetweenFrames();
  TestCutIdleLine();
  TearDown();
  return ja_test::Finish("test_sim_board");
}
