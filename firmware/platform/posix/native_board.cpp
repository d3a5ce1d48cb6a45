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
#include <signal.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <string>
#include <vector>

#include "app/app.hpp"
#include "app/hal.hpp"
#include "app/tx_ring.hpp"
#include "protocol/messages.hpp"
#include "sim/board_common/options.hpp"
#include "sim/board_common/rig_load.hpp"
#include "sim/board_common/sensor_faults.hpp"
#include "sim/board_common/serial_line.hpp"
#include "sim/devices/ja_sim_devices.h"

namespace ja {
namespace posix {
namespace {

volatile sig_atomic_t g_stop = 0;
void OnSignal(int) { g_stop = 1; }

using board::MonotonicNs;

constexpr uint32_t kDefaultBaud = 500000;

bool ParseArgs(int argc, char** argv, board::CommonOptions* o) {
  for (int i = 1; i < argc; ++i) {
    const board::ArgResult r = board::ParseCommonArg(argc, argv, &i, o);
    if (r == board::ArgResult::kBad) return false;
    if (r == board::ArgResult::kNotCommon) {
      std::fprintf(stderr, "ja_native_board: unknown argument %s\n", argv[i]);
      return false;
    }
  }
  if (o->baud == 0) o->baud = kDefaultBaud;
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
  /// Opens (or creates, erased to 0xFF) the file; `fresh` tells whether it was created. False
  /// with *error set when it cannot, or when the file is not an EEPROM image of this board
  /// (board::EepromFileFits: then it is left as it is).
  bool Open(const std::string& path, bool* fresh, std::string* error) {
    fd_ = open(path.c_str(), O_RDWR | O_CREAT, 0644);
    if (fd_ < 0) {
      *error = "cannot open the EEPROM file " + path + ": " + std::strerror(errno);
      return false;
    }
    if (!board::EepromFileFits(fd_, path, kSize, error)) return false;
    data_.assign(kSize, 0xFF);
    const ssize_t n = pread(fd_, data_.data(), kSize, 0);
    if (n < 0) {
      *error = "cannot read the EEPROM file " + path + ": " + std::strerror(errno);
      return false;
    }
    *fresh = n == 0;
    if (n < kSize) {
      std::fill(data_.begin() + n, data_.end(), 0xFF);
      if (pwrite(fd_, data_.data(), kSize, 0) != kSize) {
        *error = "cannot write the EEPROM file " + path + ": " + std::strerror(errno);
        return false;
      }
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

// ---- The UART: the app writes into a TxRing (255 bytes); bytes leave it at the baud rate (10
// bits per byte) in simulated time and go on the pty's wire. When the pty does not take them (the
// host is not reading), they wait on the wire (bounded): the ring then fills and the app drops and
// counts whole frames, as on the AVR. Fault injection applies to bytes on the wire. ----
class Uart final : public app::SerialPort {
 public:
  Uart(SimClock& clock, board::Pty& pty, const board::CommonOptions& o)
      : clock_(clock),
        pty_(pty),
        byte_ns_(10000000000ull / o.baud),
        faults_(o.corrupt_every, o.drop_every) {}

  uint16_t TxFree() override { return ring_.Free(); }
  void TxWrite(const uint8_t* data, uint16_t n) override {
    const uint64_t now = clock_.NowNs();
    if (ring_.Used() == 0 && line_ns_ < now) line_ns_ = now;  // the line was idle
    ring_.Write(data, n);
  }
  int16_t RxRead() override {
    if (rx_.empty()) return -1;
    const uint8_t b = rx_.front();
    rx_.pop_front();
    return b;
  }

  /// Reads what the host sent (non-blocking).
  void Receive() { pty_.Receive(&rx_); }
  /// Moves the bytes whose transmission ended by `now` to the pty.
  void Drain(uint64_t now) {
    pty_.Flush();
    if (pty_.waiting() >= kWireMax) {
      line_ns_ = std::max(line_ns_, now);  // the line waits for the host
      return;
    }
    uint8_t b;
    while (ring_.Used() > 0 && line_ns_ + byte_ns_ <= now && pty_.waiting() < kWireMax &&
           ring_.Pop(&b)) {
      line_ns_ += byte_ns_;
      if (faults_.Pass(++bytes_, &b)) pty_.Send(b);
    }
    pty_.Flush();
  }
  /// When the ring will have drained (bytes in it leave at the baud rate).
  uint64_t EmptyAt() const { return line_ns_ + ring_.Used() * byte_ns_; }
  bool idle() const { return ring_.Used() == 0; }
  bool blocked() const { return pty_.waiting() > 0; }
  uint64_t bytes() const { return bytes_; }
  uint64_t dropped() const { return faults_.dropped(); }
  uint64_t corrupted() const { return faults_.corrupted(); }

 private:
  static constexpr size_t kWireMax = 4096;

  SimClock& clock_;
  board::Pty& pty_;
  const uint64_t byte_ns_;
  board::SerialFaults faults_;
  app::TxRing ring_;
  uint64_t line_ns_ = 0;  // when the byte now on the line ends
  std::deque<uint8_t> rx_;
  uint64_t bytes_ = 0;
};

int Run(int argc, char** argv) {
  board::SetProgramName("ja_native_board");
  board::CommonOptions opt;
  if (!ParseArgs(argc, argv, &opt)) {
    board::PrintUsage("");
    return 2;
  }
  app::Config cfg;
  const board::SimPtr sim_owner = board::LoadRig(&opt, &cfg);
  if (!sim_owner) return 2;
  ja_sim* sim = sim_owner.get();

  // EEPROM: the rig's configuration is written into a fresh EEPROM (state ok); an existing
  // --eeprom file is kept as it is (what a previous run saved).
  std::string tmpdir;
  if (opt.eeprom.empty()) {
    tmpdir = board::MakeTempDir("ja-native");
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
  std::string eeprom_error;
  if (!eeprom.Open(opt.eeprom, &fresh, &eeprom_error)) {
    std::fprintf(stderr, "ja_native_board: %s\n", eeprom_error.c_str());
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
  board::Pty pty;
  Uart uart(clock, pty, opt);
  RebootFlag reboot;
  const app::Hal hal{
      bus, wait, clock, uart, eeprom, reboot, static_cast<uint8_t>(proto::Board::kNative)};
  app::App app(hal);
  if (!pty.Open(opt.link)) return 1;
  board::ApplySensorFaults(sim, &opt.faults, clock.NowNs());  // a fault @0 is there from power-up
  app.Begin();

  const uint64_t disconnect_ns =
      opt.disconnect_after_s >= 0 ? static_cast<uint64_t>(opt.disconnect_after_s * 1e9) : ~0ull;
  board::Cable cable(pty, opt.link, opt.reconnect_after_s);
  bool ran_fast = false;
  while (!g_stop) {
    // --disconnect-after: the host reads what was sent before the cut, then the cable comes out.
    if (!cable.pulled() && clock.NowNs() >= disconnect_ns)
      cable.Pull([&] { uart.Drain(clock.NowNs()); }, &g_stop);
    if (!cable.Service()) return 1;
    uart.Drain(clock.NowNs());
    uart.Receive();
    board::ApplySensorFaults(sim, &opt.faults, clock.NowNs());
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
      pty.Wait(std::min<uint64_t>(next - wall, 50000000ull));
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
