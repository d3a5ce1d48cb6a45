// The C ABI of ja_sim_board.h: one board's common options, rig, settings file, fault schedule and
// line, each the board_common piece the C++ boards use.
#include "sim/board_common/ja_sim_board.h"

#include <signal.h>

#include <algorithm>
#include <cstddef>
#include <cstdio>
#include <deque>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "app/app_config.hpp"
#include "sim/board_common/options.hpp"
#include "sim/board_common/rig_load.hpp"
#include "sim/board_common/sensor_faults.hpp"
#include "sim/board_common/serial_line.hpp"
#include "sim/board_common/settings_file.hpp"

namespace {

constexpr uint64_t kIdleCutNs = 1000000;  // a line this long without a byte is between frames

/// Why the last ja_sim_board_open on this thread failed.
std::string& OpenError() {
  static thread_local std::string error;
  return error;
}

// Cable::Pull stops early on a signal the C++ boards catch; here the caller owns the signals, and
// the pull takes at most 2 s.
const volatile sig_atomic_t kNeverStop = 0;

}  // namespace

struct ja_sim_board {
  ja_sim_board(ja::board::CommonOptions&& o, const ja::app::Config& c, ja::board::SimPtr&& s)
      : opt(std::move(o)), cfg(c), sim(std::move(s)) {}

  ja::board::CommonOptions opt;
  ja::app::Config cfg;
  ja::board::SimPtr sim;
  ja::board::SettingsFile settings;
  ja::board::Pty pty;  // before line and cable, which refer to it
  ja::board::UartLine line{pty, opt};
  ja::board::Cable cable{pty, opt.link, opt.reconnect_after_s};
  bool line_opened = false;
  uint64_t rx_bytes = 0, disconnects = 0;
  std::string error;

  int Fail(const std::string& why) {
    error = why;
    return JA_SIM_EINVAL;
  }
};

extern "C" {

uint32_t ja_sim_board_abi_version(void) { return JA_SIM_BOARD_ABI_VERSION; }

ja_sim_board* ja_sim_board_open(int argc, const char* const* argv, const char* board_usage) {
  OpenError().clear();
  if (argc < 1 || argv == nullptr || argv[0] == nullptr) {
    OpenError() = "no argv[0] (the board's name)";
    return nullptr;
  }
  for (int i = 0; i < argc; ++i) {
    if (argv[i] == nullptr) {
      OpenError() = "argv[" + std::to_string(i) + "] is NULL";
      return nullptr;
    }
  }
  const std::string name = argv[0];
  ja::board::SetProgramName(name.substr(name.rfind('/') + 1).c_str());
  std::vector<std::string> args(argv, argv + argc);
  std::vector<char*> av;
  for (std::string& a : args) av.push_back(&a[0]);
  av.push_back(nullptr);

  ja::board::CommonOptions o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = av[i];
    const ja::board::ArgResult r = ja::board::ParseCommonArg(argc, av.data(), &i, &o);
    if (r == ja::board::ArgResult::kBad) {
      OpenError() = a + ": a missing or malformed value";
    } else if (r == ja::board::ArgResult::kNotCommon) {
      OpenError() = "unknown argument " + a;
      std::fprintf(stderr, "%s: %s\n", ja::board::ProgramName(), OpenError().c_str());
    }
    if (r != ja::board::ArgResult::kTaken) break;
  }
  if (OpenError().empty() && (o.rig.empty() || o.motion.empty()))
    OpenError() = "--rig and --motion are required";
  if (!OpenError().empty()) {
    ja::board::PrintUsage(board_usage);
    return nullptr;
  }
  ja::app::Config cfg{};
  ja::board::SimPtr sim = ja::board::LoadRig(&o, &cfg, &OpenError());
  if (!sim) {
    std::fprintf(stderr, "%s: %s\n", ja::board::ProgramName(), OpenError().c_str());
    return nullptr;
  }
  return new ja_sim_board(std::move(o), cfg, std::move(sim));
}

void ja_sim_board_close(ja_sim_board* b) {
  if (b == nullptr) return;
  b->pty.Flush();
  delete b;
}

const char* ja_sim_board_last_error(const ja_sim_board* b) {
  return b ? b->error.c_str() : OpenError().c_str();
}

ja_sim* ja_sim_board_sim(const ja_sim_board* b) { return b ? b->sim.get() : nullptr; }
uint32_t ja_sim_board_baud(const ja_sim_board* b) { return b ? b->opt.baud : 0; }
int ja_sim_board_fast(const ja_sim_board* b) { return b && b->opt.fast ? 1 : 0; }
int ja_sim_board_loop_motion(const ja_sim_board* b) { return b && b->opt.loop_motion ? 1 : 0; }
int ja_sim_board_cold_start(const ja_sim_board* b) { return b && b->opt.cold_start ? 1 : 0; }
double ja_sim_board_disconnect_after_s(const ja_sim_board* b) {
  return b ? b->opt.disconnect_after_s : -1;
}
double ja_sim_board_reconnect_after_s(const ja_sim_board* b) {
  return b ? b->opt.reconnect_after_s : -1;
}
const char* ja_sim_board_link(const ja_sim_board* b) { return b ? b->opt.link.c_str() : ""; }
uint32_t ja_sim_board_rate_hz(const ja_sim_board* b) { return b ? b->cfg.rate_hz : 0; }

int ja_sim_board_settings_open(ja_sim_board* b, uint8_t* image, size_t size, uint32_t flags) {
  if (b == nullptr) return JA_SIM_EINVAL;
  if (image == nullptr) return b->Fail("settings_open: no image buffer");
  if (size == 0 || size > 0xFFFF)
    return b->Fail("settings_open: a store of " + std::to_string(size) + " bytes (1..65535)");
  std::string error;
  const std::string prefix = std::string(ja::board::ProgramName()) + "-settings";
  if (!b->settings.Open(b->opt.eeprom, static_cast<uint32_t>(size), b->cfg,
                        (flags & JA_SIM_BOARD_SETTINGS_ERASED) != 0, prefix.c_str(), &error)) {
    return b->Fail(error);
  }
  std::copy(b->settings.image().begin(), b->settings.image().end(), image);
  return JA_SIM_OK;
}

int ja_sim_board_settings_write(ja_sim_board* b, const uint8_t* image, size_t size) {
  if (b == nullptr) return JA_SIM_EINVAL;
  if (!b->settings.is_open()) return b->Fail("settings_write: the settings file is not open");
  if (image == nullptr || size != b->settings.image().size()) {
    return b->Fail("settings_write: " + std::to_string(size) + " bytes for " + b->settings.path() +
                   ", a store of " + std::to_string(b->settings.image().size()));
  }
  const bool was_ok = b->settings.ok();
  const uint32_t changed = b->settings.Persist(image);
  if (was_ok && !b->settings.ok())
    return b->Fail("settings_write: cannot write the EEPROM file " + b->settings.path());
  return static_cast<int>(changed);
}

const char* ja_sim_board_settings_path(const ja_sim_board* b) {
  return b ? b->settings.path().c_str() : "";
}

int ja_sim_board_apply_faults(ja_sim_board* b, uint64_t t_ns) {
  if (b == nullptr) return JA_SIM_EINVAL;
  ja::board::ApplySensorFaults(b->sim.get(), &b->opt.faults, t_ns);
  return JA_SIM_OK;
}

int ja_sim_board_line_open(ja_sim_board* b) {
  if (b == nullptr) return JA_SIM_EINVAL;
  if (b->pty.open()) return b->Fail("line_open: the pty " + b->pty.path() + " is open already");
  if (!b->pty.Open(b->opt.link)) return b->Fail("line_open: cannot open a pty");
  b->line_opened = true;
  return JA_SIM_OK;
}

int ja_sim_board_line_put(ja_sim_board* b, uint8_t byte, uint64_t t_ns) {
  if (b == nullptr) return JA_SIM_EINVAL;
  const size_t before = b->pty.waiting();
  b->line.Transmit(byte, t_ns);
  return b->pty.waiting() > before ? 1 : 0;
}

int ja_sim_board_line_take(ja_sim_board* b, uint8_t* buf, size_t cap) {
  if (b == nullptr) return JA_SIM_EINVAL;
  if (buf == nullptr && cap > 0) return b->Fail("line_take: no buffer");
  std::deque<uint8_t>& rx = b->line.rx();
  if (rx.size() < cap) b->line.Receive();
  const size_t n = std::min({cap, rx.size(), static_cast<size_t>(1u << 30)});
  std::copy(rx.begin(), rx.begin() + static_cast<std::ptrdiff_t>(n), buf);
  rx.erase(rx.begin(), rx.begin() + static_cast<std::ptrdiff_t>(n));
  b->rx_bytes += n;
  return static_cast<int>(n);
}

int ja_sim_board_line_flush(ja_sim_board* b) {
  if (b == nullptr) return JA_SIM_EINVAL;
  b->line.Flush();
  return JA_SIM_OK;
}

size_t ja_sim_board_line_waiting(const ja_sim_board* b) { return b ? b->pty.waiting() : 0; }

int ja_sim_board_line_wait(ja_sim_board* b, uint64_t ns) {
  if (b == nullptr) return JA_SIM_EINVAL;
  b->pty.Wait(ns);
  return JA_SIM_OK;
}

int ja_sim_board_line_service(ja_sim_board* b, uint64_t t_ns) {
  if (b == nullptr) return JA_SIM_EINVAL;
  if (!b->line_opened) return 0;
  // As the AVR board: the cut is armed once S simulated seconds have passed; it comes after the
  // delimiter of the frame on the line, or at once on a line idle for 1 ms.
  const double s = b->opt.disconnect_after_s;
  const uint64_t disconnect_ns = s < 0 ? ~0ull : static_cast<uint64_t>(s * 1e9);
  int result = 0;
  if (!b->cable.pulled() && t_ns >= disconnect_ns) b->line.ArmCut(t_ns, kIdleCutNs);
  if (!b->cable.pulled() && b->line.CutReady()) {
    b->cable.Pull([b] { b->line.Flush(); }, &kNeverStop);
    b->line.Disconnected();
    ++b->disconnects;
    result = JA_SIM_BOARD_LINE_PULLED;
  }
  const bool was_open = b->pty.open();
  if (!b->cable.Service()) return b->Fail("line_service: cannot open a new pty");
  if (!was_open && b->pty.open()) result = JA_SIM_BOARD_LINE_RECONNECTED;
  return result;
}

int ja_sim_board_line_connected(const ja_sim_board* b) { return b && b->pty.open() ? 1 : 0; }

const char* ja_sim_board_line_path(const ja_sim_board* b) { return b ? b->pty.path().c_str() : ""; }

int ja_sim_board_line_get_counters(const ja_sim_board* b, ja_sim_board_line_counters* out,
                                   size_t size) {
  if (b == nullptr || out == nullptr || size != sizeof(ja_sim_board_line_counters))
    return JA_SIM_EINVAL;
  *out = ja_sim_board_line_counters{b->line.tx_bytes(),       b->rx_bytes,
                                    b->line.dropped(),        b->line.corrupted(),
                                    b->line.bridge_dropped(), b->disconnects};
  return JA_SIM_OK;
}

}  // extern "C"
