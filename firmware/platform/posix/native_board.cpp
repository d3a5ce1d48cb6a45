// The native virtual board (issue 5, item 2): the firmware application (firmware/app) compiled for
// Linux, its sensors the virtual devices (firmware/sim/devices) fed from an accelerations CSV, its
// UART a pseudo-terminal. Launcher contract (host/jointangle/transport.py, NativeBoardLauncher):
//
//   ja_native_board --rig RIG.toml --motion DATA.csv --baud B [--fast] [--fault SPEC]... [options]
//
// prints `PTY /dev/pts/N` (one flushed line) once the firmware runs, serves the protocol on that
// pty and exits 0 on SIGTERM. See README.md next to this file for the options and the timing.
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <pty.h>
#include <signal.h>
#include <sys/ioctl.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "app/app.hpp"
#include "app/hal.hpp"
#include "app/tx_ring.hpp"
#include "platform/posix/rig_toml.hpp"
#include "protocol/messages.hpp"
#include "sim/devices/ja_sim_devices.h"

namespace ja {
namespace posix {
namespace {

volatile sig_atomic_t g_stop = 0;
void OnSignal(int) { g_stop = 1; }

uint64_t MonotonicNs() {
  timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<uint64_t>(ts.tv_sec) * 1000000000ull + static_cast<uint64_t>(ts.tv_nsec);
}

// One scheduled sensor fault (--fault SENSOR:KIND[=PARAM]@START[-END], simulated seconds).
struct FaultSpec {
  std::string sensor;  // motion id ("a.0") or "mux"
  int kind = 0;        // JA_SIM_FAULT_*
  uint32_t param = 0;
  uint64_t start_ns = 0, end_ns = ~0ull;  // ~0: never cleared
  int dev = -1;
  bool on = false, done = false;
};

struct Options {
  std::string rig, motion, eeprom, link;
  std::vector<FaultSpec> faults;
  uint32_t baud = 500000;
  bool fast = false;
  uint64_t corrupt_every = 0, drop_every = 0;
  double disconnect_after_s = -1, reconnect_after_s = -1;
  bool loop_motion = false;
};

void Usage() {
  std::fprintf(stderr,
               "usage: ja_native_board --rig RIG.toml --motion DATA.csv [--baud B] [--fast]\n"
               "  [--eeprom FILE] [--link PATH] [--loop-motion] [--corrupt-every N]\n"
               "  [--drop-every N] [--disconnect-after S] [--reconnect-after S]\n"
               "  [--fault SENSOR:KIND[=PARAM]@START[-END]]...  (repeatable)\n"
               "    SENSOR a.0, a.1, b.0, ... (rig order) or mux; KIND nack, wrong_id,\n"
               "    saturate, frozen (PARAM: firmware/sim/devices/i2c_target.hpp FaultKind);\n"
               "    START, END in simulated seconds (no END: until the board stops)\n"
               "    e.g. --fault a.0:nack@2.0-4.0 --fault b.1:frozen@1\n");
}

/// Parses SENSOR:KIND[=PARAM]@START[-END]; false with *why on a malformed spec.
bool ParseFault(const std::string& text, FaultSpec* f, std::string* why) {
  const size_t colon = text.find(':'), at = text.find('@');
  if (colon == std::string::npos || at == std::string::npos || colon == 0 || at < colon) {
    *why = "expected SENSOR:KIND[=PARAM]@START[-END], e.g. a.0:nack@2-4";
    return false;
  }
  f->sensor = text.substr(0, colon);
  std::string kind = text.substr(colon + 1, at - colon - 1);
  const size_t eq = kind.find('=');
  if (eq != std::string::npos) {
    const std::string v = kind.substr(eq + 1);
    char* end = nullptr;
    const unsigned long n = std::strtoul(v.c_str(), &end, 0);
    if (v.empty() || *end != '\0' || v[0] == '-' || n > 0xFFFFFFFFul) {
      *why = "PARAM must be a non-negative integer";
      return false;
    }
    f->param = static_cast<uint32_t>(n);
    kind = kind.substr(0, eq);
  }
  static const struct {
    const char* name;
    int kind;
  } kKinds[] = {{"nack", JA_SIM_FAULT_NACK},          {"wrong_id", JA_SIM_FAULT_WRONG_ID},
                {"wrong-id", JA_SIM_FAULT_WRONG_ID},  {"saturate", JA_SIM_FAULT_SATURATE},
                {"saturated", JA_SIM_FAULT_SATURATE}, {"frozen", JA_SIM_FAULT_FROZEN}};
  for (const auto& k : kKinds) {
    if (kind == k.name) f->kind = k.kind;
  }
  if (f->kind == 0) {
    *why = "unknown fault kind '" + kind + "' (nack, wrong_id, saturate, frozen)";
    return false;
  }
  const std::string times = text.substr(at + 1);
  char* end = nullptr;
  const double start = std::strtod(times.c_str(), &end);
  double stop = -1;
  if (end != times.c_str() && *end == '-') {
    const char* s2 = end + 1;
    stop = std::strtod(s2, &end);
    if (end == s2) end = const_cast<char*>(s2 - 1);  // "2-": malformed
  }
  if (times.empty() || *end != '\0' || !(start >= 0) || (stop >= 0 && !(stop > start)) ||
      start > 1e6 || stop > 1e6) {
    *why = "START[-END] must be seconds with END > START >= 0";
    return false;
  }
  f->start_ns = static_cast<uint64_t>(start * 1e9 + 0.5);
  if (stop >= 0) f->end_ns = static_cast<uint64_t>(stop * 1e9 + 0.5);
  return true;
}

bool ParseArgs(int argc, char** argv, Options* o) {
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&](std::string* out) {
      if (i + 1 >= argc) return false;
      *out = argv[++i];
      return true;
    };
    std::string v;
    char* end = nullptr;
    if (a == "--fast") {
      o->fast = true;
    } else if (a == "--loop-motion") {
      o->loop_motion = true;
    } else if (a == "--fault") {
      FaultSpec f;
      std::string why;
      if (!next(&v)) return false;
      if (!ParseFault(v, &f, &why)) {
        std::fprintf(stderr, "ja_native_board: --fault %s: %s\n", v.c_str(), why.c_str());
        return false;
      }
      o->faults.push_back(f);
    } else if (a == "--rig") {
      if (!next(&o->rig)) return false;
    } else if (a == "--motion") {
      if (!next(&o->motion)) return false;
    } else if (a == "--eeprom") {
      if (!next(&o->eeprom)) return false;
    } else if (a == "--link") {
      if (!next(&o->link)) return false;
    } else if (a == "--baud" || a == "--corrupt-every" || a == "--drop-every") {
      if (!next(&v)) return false;
      const unsigned long long n = std::strtoull(v.c_str(), &end, 10);
      if (*end != '\0' || v.empty() || v[0] == '-') return false;
      if (a == "--baud") {
        if (n < 300 || n > 10000000) return false;
        o->baud = static_cast<uint32_t>(n);
      } else if (a == "--corrupt-every") {
        o->corrupt_every = n;
      } else {
        o->drop_every = n;
      }
    } else if (a == "--disconnect-after" || a == "--reconnect-after") {
      if (!next(&v)) return false;
      const double s = std::strtod(v.c_str(), &end);
      if (*end != '\0' || v.empty() || !(s >= 0)) return false;
      (a == "--disconnect-after" ? o->disconnect_after_s : o->reconnect_after_s) = s;
    } else {
      std::fprintf(stderr, "ja_native_board: unknown argument %s\n", a.c_str());
      return false;
    }
  }
  return !o->rig.empty() && !o->motion.empty();
}

// ---- Simulated time. It moves from event to event (a loop due, the transmit ring drained, a
// received byte), never while the firmware runs. With --fast it jumps to the next event at once;
// in real time it waits until the wall clock reaches it, and when the board was scheduled late it
// catches up loop by loop (bytes still paced in simulated time) instead of losing loops, unless it
// is more than kMaxLagNs behind: then it jumps and the app counts the overruns. ----
class SimClock final : public app::Clock {
 public:
  static constexpr uint64_t kMaxLagNs = 1000000000ull;
  explicit SimClock(bool fast) : fast_(fast), start_(MonotonicNs()) {}
  uint64_t NowNs() const { return sim_ns_; }
  uint32_t NowUs() override { return static_cast<uint32_t>(sim_ns_ / 1000u); }
  /// The wall clock on the simulated time line: wall time since the last Anchor() plus the
  /// simulated time then (real-time pacing resumes from where fast running left it).
  uint64_t WallNs() const { return MonotonicNs() - start_; }
  /// Restarts real-time pacing from the current simulated time.
  void Anchor() { start_ = MonotonicNs() - sim_ns_; }
  /// Jumps forward to t (never back).
  void AdvanceTo(uint64_t t) { sim_ns_ = std::max(sim_ns_, t); }
  bool fast() const { return fast_; }

 private:
  bool fast_;
  uint64_t start_;
  uint64_t sim_ns_ = 0;
};

// ---- Scheduled sensor faults (--fault), switched in simulated time before each Poll. ----
bool ResolveFaults(ja_sim* sim, std::vector<FaultSpec>* faults) {
  for (FaultSpec& f : *faults) {
    f.dev = -1;
    if (f.sensor == "mux") {
      for (int d = 0; d < ja_sim_device_count(sim) && f.dev < 0; ++d) {
        int model = 0;
        if (ja_sim_device_info(sim, d, &model, nullptr, nullptr, nullptr) == JA_SIM_OK &&
            model == JA_SIM_TCA9548A)
          f.dev = d;
      }
    } else {
      f.dev = ja_sim_find_device(sim, f.sensor.c_str());
    }
    if (f.dev < 0) {
      std::fprintf(stderr,
                   "ja_native_board: --fault: the rig has no sensor '%s' (a.0, a.1, ..., "
                   "b.0, ... in rig order, or mux)\n",
                   f.sensor.c_str());
      return false;
    }
  }
  return true;
}

void ApplyFaults(ja_sim* sim, std::vector<FaultSpec>* faults, uint64_t now_ns) {
  for (FaultSpec& f : *faults) {
    if (f.done) continue;
    if (!f.on && now_ns >= f.start_ns) {
      if (ja_sim_inject_fault(sim, f.dev, f.kind, f.param) != JA_SIM_OK) {
        std::fprintf(stderr, "ja_native_board: --fault %s: %s\n", f.sensor.c_str(),
                     ja_sim_last_error(sim));
        f.done = true;
        continue;
      }
      f.on = true;
      std::fprintf(stderr, "ja_native_board: %.3f s: fault %d on %s\n", now_ns * 1e-9, f.kind,
                   f.sensor.c_str());
    }
    if (f.on && now_ns >= f.end_ns) {
      ja_sim_clear_fault(sim, f.dev, f.kind);
      f.on = false;
      f.done = true;
      std::fprintf(stderr, "ja_native_board: %.3f s: fault %d off %s\n", now_ns * 1e-9, f.kind,
                   f.sensor.c_str());
    }
  }
}

// ---- The virtual devices behind the drivers' bus. Device time follows the board's clock. ----
class SimBus final : public drivers::I2cBus {
 public:
  SimBus(ja_sim* sim, SimClock& clock) : sim_(sim), clock_(clock) {}
  drivers::I2cStatus Read(uint8_t addr7, uint8_t reg, uint8_t* buf, uint8_t n) override {
    ja_sim_set_time_ns(sim_, clock_.NowNs());
    return Status(ja_sim_i2c_write_read(sim_, addr7, &reg, 1, buf, n));
  }
  drivers::I2cStatus Write(uint8_t addr7, uint8_t reg, const uint8_t* buf, uint8_t n) override {
    uint8_t frame[256];
    frame[0] = reg;
    std::memcpy(frame + 1, buf, n);
    ja_sim_set_time_ns(sim_, clock_.NowNs());
    return Status(ja_sim_i2c_write(sim_, addr7, frame, static_cast<size_t>(n) + 1u));
  }

 private:
  static drivers::I2cStatus Status(int r) {
    if (r == JA_SIM_OK) return drivers::I2cStatus::kOk;
    if (r == JA_SIM_ADDRESS_NACK || r == JA_SIM_DATA_NACK) return drivers::I2cStatus::kNack;
    return drivers::I2cStatus::kBusError;
  }
  ja_sim* sim_;
  SimClock& clock_;
};

class SimWait final : public drivers::Delay {
 public:
  explicit SimWait(SimClock& clock) : clock_(clock) {}
  void WaitMs(uint16_t ms) override {
    clock_.AdvanceTo(clock_.NowNs() + ms * 1000000ull);
    if (!clock_.fast()) {
      timespec ts{ms / 1000, static_cast<long>(ms % 1000) * 1000000L};
      while (nanosleep(&ts, &ts) != 0 && errno == EINTR && !g_stop) {
      }
    }
  }

 private:
  SimClock& clock_;
};

// ---- EEPROM: 4 KB (the ATmega2560's), kept in a file so resets and restarts keep it. ----
class FileEeprom final : public app::Eeprom {
 public:
  static constexpr uint16_t kSize = 4096;
  ~FileEeprom() {
    if (fd_ >= 0) close(fd_);
  }
  /// Opens (or creates, erased to 0xFF) the file; `fresh` tells whether it was created.
  bool Open(const std::string& path, bool* fresh) {
    fd_ = open(path.c_str(), O_RDWR | O_CREAT, 0644);
    if (fd_ < 0) return false;
    data_.assign(kSize, 0xFF);
    const ssize_t n = pread(fd_, data_.data(), kSize, 0);
    if (n < 0) return false;
    *fresh = n == 0;
    if (n < kSize) {
      std::fill(data_.begin() + n, data_.end(), 0xFF);
      if (pwrite(fd_, data_.data(), kSize, 0) != kSize) return false;
    }
    return true;
  }
  uint16_t Size() override { return kSize; }
  uint8_t Read(uint16_t addr) override { return addr < kSize ? data_[addr] : 0xFF; }
  void Write(uint16_t addr, uint8_t value) override {
    if (addr >= kSize || data_[addr] == value) return;  // eeprom_update_byte
    data_[addr] = value;
    if (pwrite(fd_, &value, 1, addr) != 1) failed_ = true;
  }
  bool failed() const { return failed_; }

 private:
  int fd_ = -1;
  std::vector<uint8_t> data_;
  bool failed_ = false;
};

class RebootFlag final : public app::System {
 public:
  void Reboot() override { pending = true; }
  bool pending = false;
};

// ---- The pseudo-terminal: raw, the master non-blocking; the board keeps the slave open too so
// the host can close and reopen it without the master seeing a hang-up. ----
class Pty {
 public:
  ~Pty() { Close(); }
  bool Open(const std::string& link) {
    char name[128];
    if (openpty(&master_, &slave_, name, nullptr, nullptr) != 0) return false;
    termios t;
    if (tcgetattr(slave_, &t) == 0) {
      cfmakeraw(&t);
      tcsetattr(slave_, TCSANOW, &t);
    }
    fcntl(master_, F_SETFL, fcntl(master_, F_GETFL) | O_NONBLOCK);
    fcntl(master_, F_SETFD, FD_CLOEXEC);
    fcntl(slave_, F_SETFD, FD_CLOEXEC);
    path_ = name;
    link_ = link;
    if (!link_.empty()) {
      const std::string tmp = link_ + ".tmp";
      unlink(tmp.c_str());
      if (symlink(path_.c_str(), tmp.c_str()) != 0 || rename(tmp.c_str(), link_.c_str()) != 0) {
        std::fprintf(stderr, "ja_native_board: cannot link %s: %s\n", link_.c_str(),
                     std::strerror(errno));
      }
    }
    std::printf("PTY %s\n", path_.c_str());
    std::fflush(stdout);
    return true;
  }
  void Close() {
    if (master_ >= 0) close(master_);
    if (slave_ >= 0) close(slave_);
    master_ = slave_ = -1;
    if (!link_.empty()) unlink(link_.c_str());
  }
  bool open() const { return master_ >= 0; }
  int master() const { return master_; }
  /// Bytes written to the master that the host has not read yet.
  int Unread() const {
    int n = 0;
    return (slave_ >= 0 && ioctl(slave_, FIONREAD, &n) == 0) ? n : 0;
  }

 private:
  int master_ = -1, slave_ = -1;
  std::string path_, link_;
};

// ---- The UART: the app writes into a TxRing (255 bytes); bytes leave it at the baud rate (10
// bits per byte) in simulated time and go to the pty. When the pty does not take them (the host
// is not reading), they wait in `wire_` (bounded): the ring then fills and the app drops and counts
// whole frames, as on the AVR. Fault injection applies to bytes on the wire. ----
class Uart final : public app::SerialPort {
 public:
  Uart(SimClock& clock, Pty& pty, const Options& o)
      : clock_(clock), pty_(pty), byte_ns_(10000000000ull / o.baud), opt_(o) {}

  uint16_t TxFree() override { return ring_.Free(); }
  void TxWrite(const uint8_t* data, uint16_t n) override {
    const uint64_t now = clock_.NowNs();
    if (ring_.Used() == 0 && line_ns_ < now) line_ns_ = now;  // the line was idle
    ring_.Write(data, n);
  }
  int16_t RxRead() override {
    if (rx_pos_ >= rx_.size()) return -1;
    const uint8_t b = rx_[rx_pos_++];
    if (rx_pos_ == rx_.size()) rx_.clear(), rx_pos_ = 0;
    return b;
  }

  /// Reads what the host sent (non-blocking).
  void Receive() {
    if (!pty_.open()) return;
    uint8_t buf[512];
    for (;;) {
      const ssize_t n = read(pty_.master(), buf, sizeof buf);
      if (n <= 0) break;
      rx_.insert(rx_.end(), buf, buf + n);
    }
  }
  /// Moves the bytes whose transmission ended by `now` to the pty.
  void Drain(uint64_t now) {
    Flush();
    if (wire_.size() >= kWireMax) {
      line_ns_ = std::max(line_ns_, now);  // the line waits for the host
      return;
    }
    uint8_t b;
    while (ring_.Used() > 0 && line_ns_ + byte_ns_ <= now && wire_.size() < kWireMax &&
           ring_.Pop(&b)) {
      line_ns_ += byte_ns_;
      ++bytes_;
      if (opt_.drop_every && bytes_ % opt_.drop_every == 0) {
        ++dropped_;
        continue;
      }
      if (opt_.corrupt_every && bytes_ % opt_.corrupt_every == 0) {
        b ^= 0x5A;
        ++corrupted_;
      }
      if (pty_.open()) wire_.push_back(b);
    }
    Flush();
  }
  /// When the ring will have drained (bytes in it leave at the baud rate).
  uint64_t EmptyAt() const { return line_ns_ + ring_.Used() * byte_ns_; }
  bool idle() const { return ring_.Used() == 0; }
  bool blocked() const { return !wire_.empty(); }
  void Disconnected() { wire_.clear(); }
  uint64_t bytes() const { return bytes_; }
  uint64_t dropped() const { return dropped_; }
  uint64_t corrupted() const { return corrupted_; }

 private:
  static constexpr size_t kWireMax = 4096;
  void Flush() {
    if (wire_.empty()) return;
    if (!pty_.open()) {
      wire_.clear();
      return;
    }
    const ssize_t n = write(pty_.master(), wire_.data(), wire_.size());
    if (n > 0) wire_.erase(wire_.begin(), wire_.begin() + n);
  }

  SimClock& clock_;
  Pty& pty_;
  const uint64_t byte_ns_;
  const Options& opt_;
  app::TxRing ring_;
  uint64_t line_ns_ = 0;  // when the byte now on the line ends
  std::vector<uint8_t> wire_;
  std::vector<uint8_t> rx_;
  size_t rx_pos_ = 0;
  uint64_t bytes_ = 0, dropped_ = 0, corrupted_ = 0;
};

std::string MakeTempDir() {
  const char* base = std::getenv("TMPDIR");
  std::string tmpl = std::string(base && *base ? base : "/tmp") + "/ja-native-XXXXXX";
  std::vector<char> buf(tmpl.begin(), tmpl.end());
  buf.push_back('\0');
  if (mkdtemp(buf.data()) == nullptr) return "";
  return buf.data();
}

int Run(int argc, char** argv) {
  Options opt;
  if (!ParseArgs(argc, argv, &opt)) {
    Usage();
    return 2;
  }
  std::ifstream rig_in(opt.rig);
  if (!rig_in) {
    std::fprintf(stderr, "ja_native_board: cannot read the rig %s\n", opt.rig.c_str());
    return 2;
  }
  std::stringstream rig_text;
  rig_text << rig_in.rdbuf();
  app::Config cfg;
  std::string spec, error;
  if (!RigToConfig(rig_text.str(), &cfg, &spec, &error)) {
    std::fprintf(stderr, "ja_native_board: %s: %s\n", opt.rig.c_str(), error.c_str());
    return 2;
  }

  ja_sim* sim = ja_sim_create();
  struct SimGuard {
    ja_sim* s;
    ~SimGuard() { ja_sim_destroy(s); }
  } sim_guard{sim};
  if (ja_sim_attach_rig(sim, spec.c_str()) < 0 ||
      ja_sim_load_motion_csv(sim, opt.motion.c_str()) < 0) {
    std::fprintf(stderr, "ja_native_board: %s\n", ja_sim_last_error(sim));
    return 2;
  }
  if (opt.loop_motion) ja_sim_set_motion_loop(sim, 1);
  if (!ResolveFaults(sim, &opt.faults)) return 2;

  // EEPROM: the rig's configuration is written into a fresh EEPROM (state ok); an existing
  // --eeprom file is kept as it is (what a previous run saved).
  std::string tmpdir;
  if (opt.eeprom.empty()) {
    tmpdir = MakeTempDir();
    if (tmpdir.empty()) {
      std::fprintf(stderr, "ja_native_board: cannot create a temporary directory\n");
      return 2;
    }
    opt.eeprom = tmpdir + "/eeprom.bin";
  }
  struct TmpGuard {
    std::string dir, file;
    ~TmpGuard() {
      if (!dir.empty()) {
        unlink(file.c_str());
        rmdir(dir.c_str());
      }
    }
  } tmp_guard{tmpdir, opt.eeprom};
  FileEeprom eeprom;
  bool fresh = false;
  if (!eeprom.Open(opt.eeprom, &fresh)) {
    std::fprintf(stderr, "ja_native_board: cannot open the EEPROM file %s: %s\n",
                 opt.eeprom.c_str(), std::strerror(errno));
    return 2;
  }
  if (fresh && !app::SaveConfig(eeprom, cfg)) {
    std::fprintf(stderr, "ja_native_board: cannot write the EEPROM image\n");
    return 2;
  }

  struct sigaction sa;
  std::memset(&sa, 0, sizeof sa);
  sa.sa_handler = OnSignal;
  sigaction(SIGTERM, &sa, nullptr);
  sigaction(SIGINT, &sa, nullptr);
  signal(SIGPIPE, SIG_IGN);
  signal(SIGHUP, SIG_IGN);

  SimClock clock(opt.fast);
  SimBus bus(sim, clock);
  SimWait wait(clock);
  Pty pty;
  Uart uart(clock, pty, opt);
  RebootFlag reboot;
  const app::Hal hal{
      bus, wait, clock, uart, eeprom, reboot, static_cast<uint8_t>(proto::Board::kNative)};
  app::App app(hal);
  if (!pty.Open(opt.link)) {
    std::fprintf(stderr, "ja_native_board: openpty: %s\n", std::strerror(errno));
    return 1;
  }
  ApplyFaults(sim, &opt.faults, clock.NowNs());  // a fault @0 is there from power-up
  app.Begin();

  const uint64_t disconnect_ns =
      opt.disconnect_after_s >= 0 ? static_cast<uint64_t>(opt.disconnect_after_s * 1e9) : ~0ull;
  bool disconnected = false;
  bool ran_fast = false;
  uint64_t reconnect_at = 0;  // monotonic ns, 0 = none
  while (!g_stop) {
    const uint64_t sim_now = clock.NowNs();
    if (!disconnected && sim_now >= disconnect_ns) {
      // Let the host read what was sent before the cut, then pull the cable.
      const uint64_t deadline = MonotonicNs() + 2000000000ull;
      uint64_t quiet = MonotonicNs();
      while (MonotonicNs() < deadline && !g_stop) {
        uart.Drain(clock.NowNs());
        if (uart.blocked() || pty.Unread() > 0) quiet = MonotonicNs();
        if (MonotonicNs() - quiet > 100000000ull) break;
        usleep(2000);
      }
      // Said before the pty goes: a host that sees the hang-up then finds the line (and does
      // not reopen the old /dev/pts/N, which the system may give to another process).
      std::printf("DISCONNECTED\n");
      std::fflush(stdout);
      pty.Close();
      uart.Disconnected();
      disconnected = true;
      if (opt.reconnect_after_s >= 0)
        reconnect_at = MonotonicNs() + static_cast<uint64_t>(opt.reconnect_after_s * 1e9);
    }
    if (reconnect_at != 0 && MonotonicNs() >= reconnect_at) {
      reconnect_at = 0;
      if (!pty.Open(opt.link)) {
        std::fprintf(stderr, "ja_native_board: openpty: %s\n", std::strerror(errno));
        return 1;
      }
    }
    uart.Drain(clock.NowNs());
    uart.Receive();
    ApplyFaults(sim, &opt.faults, clock.NowNs());
    const uint32_t idle_us = app.Poll();
    if (reboot.pending) {
      reboot.pending = false;
      app.Begin();
      continue;
    }
    const uint64_t now = clock.NowNs();
    uart.Drain(now);
    uint64_t next = now + idle_us * 1000ull;
    if (!uart.idle()) next = std::min(next, std::max(now, uart.EmptyAt()));
    // --fast runs ahead only while the board streams: before the host has started the stream
    // (and after it stopped it) time passes in real time, so the motion and scheduled faults
    // are not used up before anyone watches.
    const bool run_fast = clock.fast() && app.stream_mode() != 0;
    if (run_fast != ran_fast) {
      ran_fast = run_fast;
      if (!run_fast) clock.Anchor();
    }
    if (run_fast) {
      if (uart.blocked()) {
        // The host is behind: simulated time waits for it (nothing is lost).
        pollfd p{pty.master(), POLLOUT | POLLIN, 0};
        poll(&p, 1, 20);
        continue;
      }
      clock.AdvanceTo(next);
      continue;
    }
    uint64_t wall = clock.WallNs();
    if (wall < next) {
      // Sleep until the event is due, a byte arrives or the pty takes bytes again.
      const uint64_t wait_ns = std::min<uint64_t>(next - wall, 50000000ull);
      timespec ts{static_cast<time_t>(wait_ns / 1000000000ull),
                  static_cast<long>(wait_ns % 1000000000ull)};
      if (pty.open()) {
        pollfd p{pty.master(), static_cast<short>(POLLIN | (uart.blocked() ? POLLOUT : 0)), 0};
        ppoll(&p, 1, &ts, nullptr);
      } else {
        nanosleep(&ts, nullptr);
      }
      wall = clock.WallNs();
    }
    clock.AdvanceTo(wall > next + SimClock::kMaxLagNs ? wall : std::min(next, wall));
  }
  std::fprintf(stderr,
               "ja_native_board: %.3f s simulated, %u loops, %llu bytes sent, uart_drops %u, "
               "overruns %u, injected: %llu dropped %llu corrupted\n",
               static_cast<double>(clock.NowNs()) * 1e-9, static_cast<unsigned>(app.loops()),
               static_cast<unsigned long long>(uart.bytes()),
               static_cast<unsigned>(app.uart_drops()), static_cast<unsigned>(app.loop_overruns()),
               static_cast<unsigned long long>(uart.dropped()),
               static_cast<unsigned long long>(uart.corrupted()));
  if (eeprom.failed()) std::fprintf(stderr, "ja_native_board: EEPROM file writes failed\n");
  return 0;
}

}  // namespace
}  // namespace posix
}  // namespace ja

int main(int argc, char** argv) { return ja::posix::Run(argc, argv); }
