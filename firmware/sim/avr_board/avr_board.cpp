// The AVR virtual board (issue 6, item 4): the real ATmega2560 image in simavr, its TWI bridged to
// the virtual devices (firmware/sim/devices) built from the rig file, its USART0 on a pty. Same
// launcher contract and options as the native board (firmware/platform/posix/native_board.cpp):
//
//   ja_avr_board --rig RIG.toml --motion DATA.csv [--baud B] [--fast] [options] IMAGE.elf
//   (or --elf IMAGE.elf: any Mega image, a user's Arduino sketch included)
//
// prints `PTY /dev/pts/N` once the image runs, serves the protocol on that pty, exits 0 on
// SIGTERM (or after --seconds of simulated time) and writes the loop accounting with --report.
// See README.md next to this file.
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sim_avr.h>
#include <sim_elf.h>
#include <sim_io.h>
#include <time.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "app/app_config.hpp"
#include "sim/avr_board/accounting.hpp"
#include "sim/avr_board/eeprom_file.hpp"
#include "sim/avr_board/twi_status.hpp"
#include "sim/avr_board/twi_timing.hpp"
#include "sim/avr_board/uart_link.hpp"
#include "sim/board_common/options.hpp"
#include "sim/board_common/rig_load.hpp"
#include "sim/board_common/sensor_faults.hpp"
#include "sim/board_common/serial_line.hpp"
#include "sim/devices/ja_sim_devices.h"
#include "sim/devices/simavr_twi.h"

namespace ja {
namespace avrboard {
namespace {

volatile sig_atomic_t g_stop = 0, g_measure = 0;
// After the measurement window closes the run goes on this long (simulated) so that what the
// image queued inside the window leaves its UART (a full 255-byte ring at 115 200 baud: 22 ms).
constexpr double kDrainTailS = 0.05;
void OnSignal(int) { g_stop = 1; }
void OnMeasure(int) { g_measure = 1; }

using board::MonotonicNs;

struct Options {
  board::CommonOptions common;  // --baud: 0 = the firmware's own rate
  std::string elf, report;
  double seconds = -1, measure_from_s = 0, measure_seconds = -1;
  uint32_t real_scl_hz = 400000;
  bool simavr_bus_timing = false;
  bool user_image = false;  // --elf: not necessarily the project's image (EEPROM starts erased)
  std::vector<std::pair<uint8_t, uint32_t>> stretch;  // --clock-stretch ADDR=US
  LinkOptions link;
};

bool ParseArgs(int argc, char** argv, Options* o) {
  for (int i = 1; i < argc; ++i) {
    const board::ArgResult r = board::ParseCommonArg(argc, argv, &i, &o->common);
    if (r == board::ArgResult::kBad) return false;
    if (r == board::ArgResult::kTaken) continue;
    const std::string a = argv[i];
    auto next = [&](std::string* out) {
      if (i + 1 >= argc) return false;
      *out = argv[++i];
      return true;
    };
    std::string v;
    uint64_t n = 0;
    if (a == "--elf") {  // the image named explicitly (a user's sketch: README "Your own sketch")
      if (!next(&o->elf)) return false;
      o->user_image = true;
      o->common.cold_start = true;  // as a real board: the parts power up with it
    } else if (a == "--clock-stretch") {
      // ADDR=US: the slave at ADDR (0x28, 40, ...) holds SCL US microseconds before a read.
      if (!next(&v)) return false;
      const size_t eq = v.find('=');
      char* end = nullptr;
      const unsigned long addr = eq == std::string::npos ? 0 : std::strtoul(v.c_str(), &end, 0);
      if (eq == std::string::npos || end != v.c_str() + eq || addr > 0x7F ||
          !board::ParseCount(v.substr(eq + 1), &n) || n > 100000) {
        std::fprintf(stderr, "ja_avr_board: --clock-stretch %s: expected ADDR=US\n", v.c_str());
        return false;
      }
      o->stretch.emplace_back(static_cast<uint8_t>(addr), static_cast<uint32_t>(n));
    } else if (a == "--simavr-bus-timing") {
      o->simavr_bus_timing = true;
    } else if (a == "--no-pty") {
      o->link.pty = false;
    } else if (a == "--report") {
      if (!next(&o->report)) return false;
    } else if (a == "--uart-log") {
      if (!next(&o->link.uart_log)) return false;
    } else if (a == "--scl-hz") {
      if (!next(&v) || !board::ParseCount(v, &n) || n < 1000 || n > 10000000) return false;
      o->real_scl_hz = static_cast<uint32_t>(n);
    } else if (a == "--seconds") {
      if (!next(&v) || !board::ParseSeconds(v, &o->seconds)) return false;
    } else if (a == "--measure-from") {
      if (!next(&v) || !board::ParseSeconds(v, &o->measure_from_s)) return false;
    } else if (a == "--measure-seconds") {
      if (!next(&v) || !board::ParseSeconds(v, &o->measure_seconds)) return false;
    } else if (!a.empty() && a[0] != '-' && o->elf.empty()) {
      o->elf = a;
    } else {
      std::fprintf(stderr, "ja_avr_board: unknown argument %s\n", a.c_str());
      return false;
    }
  }
  return !o->common.rig.empty() && !o->common.motion.empty() && !o->elf.empty();
}

// ---- simavr callbacks: the board is a singleton (one simulated AVR per process). ----
struct Board {
  avr_t* avr = nullptr;
  Accounting acc;
  uint64_t resets = 0;
  void (*core_reset)(avr_t*) = nullptr;
  ja_simavr_twi twi{};
};
Board g_board;

void OnActivity(avr_t* avr, avr_io_addr_t addr, uint8_t v, void*) {
  avr->data[addr] = v;
  g_board.acc.OnActivity(avr->cycle, v);
}

// Simulated time only: simavr's default sleeps in real time; the board paces itself.
void OnSleep(avr_t*, avr_cycle_count_t how_long) { g_board.acc.AddSleep(1 + how_long); }

// A watchdog (or any) reset: simavr clears the I/O space, not SRAM or the EEPROM; the core's own
// reset hook runs first. The bus forgets an open transaction.
void OnReset(avr_t* avr) {
  if (g_board.core_reset) g_board.core_reset(avr);
  ++g_board.resets;
  g_board.twi.in_transaction = 0;
  g_board.acc.OnActivity(avr->cycle, 0);
}

void LogToStderr(avr_t*, const int level, const char* format, va_list ap) {
  if (level <= LOG_WARNING) std::vfprintf(stderr, format, ap);
}

int Run(int argc, char** argv) {
  board::SetProgramName("ja_avr_board");
  Options opt;
  board::CommonOptions& common = opt.common;
  if (!ParseArgs(argc, argv, &opt)) {
    board::PrintUsage(
        "  [--report FILE.json] [--seconds S] [--measure-from S] [--measure-seconds W]\n"
        "  [--scl-hz HZ] [--simavr-bus-timing] [--clock-stretch ADDR=US]... [--uart-log FILE]\n"
        "  [--no-pty] IMAGE.elf\n"
        "  (or --elf IMAGE.elf: any ATmega2560 image, e.g. an Arduino sketch)\n");
    return 2;
  }
  app::Config cfg;
  const board::SimPtr sim_owner = board::LoadRig(&common, &cfg);
  if (!sim_owner) return 2;
  ja_sim* sim = sim_owner.get();

  // ---- The image. ----
  avr_global_logger_set(LogToStderr);
  elf_firmware_t fw;
  std::memset(&fw, 0, sizeof fw);
  if (access(opt.elf.c_str(), R_OK) != 0 || elf_read_firmware(opt.elf.c_str(), &fw) != 0) {
    std::fprintf(stderr, "ja_avr_board: cannot read the AVR image %s\n", opt.elf.c_str());
    return 2;
  }
  if (!fw.mmcu[0]) std::snprintf(fw.mmcu, sizeof fw.mmcu, "%s", "atmega2560");
  if (!fw.frequency) fw.frequency = 16000000;
  avr_t* avr = avr_make_mcu_by_name(fw.mmcu);
  if (!avr) {
    std::fprintf(stderr, "ja_avr_board: simavr has no core %s\n", fw.mmcu);
    return 2;
  }
  avr_init(avr);
  avr->log = LOG_WARNING;
  avr_load_firmware(avr, &fw);
  g_board.avr = avr;
  avr->sleep = OnSleep;
  g_board.core_reset = avr->reset;
  avr->reset = OnReset;
  const uint32_t static_end = uint32_t(avr->ioend) + 1u + fw.datasize + fw.bsssize;
  PaintStack(avr, static_end);
  avr_register_io_write(avr, kActivityAddr, OnActivity, nullptr);
  if (ja_simavr_twi_attach(&g_board.twi, avr, sim, 0) != 0) {
    std::fprintf(stderr, "ja_avr_board: %s has no TWI\n", fw.mmcu);
    return 2;
  }

  // The bus at the real SCL rate (twi_timing.hpp) unless --simavr-bus-timing; TWSR after SLA+W
  // as the ATmega2560 reports it (twi_status.hpp).
  static TwiTiming twi_timing;
  twi_timing.Attach(avr, opt.simavr_bus_timing ? 0 : opt.real_scl_hz);
  for (const auto& st : opt.stretch) twi_timing.SetStretch(st.first, st.second);
  static TwiStatus twi_status;
  twi_status.Attach(avr);

  // ---- EEPROM: the rig's configuration in a fresh file; an existing file is kept. ----
  EepromFile eeprom(avr);
  std::string eeprom_error;
  if (!eeprom.Open(common.eeprom, cfg, opt.user_image, &eeprom_error)) {
    std::fprintf(stderr, "ja_avr_board: %s\n", eeprom_error.c_str());
    return 2;
  }
  eeprom.TimeWrites();

  struct sigaction sa;
  std::memset(&sa, 0, sizeof sa);
  sa.sa_handler = OnSignal;
  sigaction(SIGTERM, &sa, nullptr);
  sigaction(SIGINT, &sa, nullptr);
  sa.sa_handler = OnMeasure;  // SIGUSR1: the measurement window starts now
  sigaction(SIGUSR1, &sa, nullptr);
  signal(SIGPIPE, SIG_IGN);
  signal(SIGHUP, SIG_IGN);

  board::Pty pty;
  UartLink uart(avr, common, opt.link, pty);
  if (!uart.Attach()) {
    std::fprintf(stderr, "ja_avr_board: cannot attach USART0 (or open --uart-log %s)\n",
                 opt.link.uart_log.c_str());
    return 2;
  }
  if (opt.link.pty && !pty.Open(common.link)) return 1;
  if (!opt.link.pty) {
    std::printf("NOPTY\n");
    std::fflush(stdout);
  }

  // ---- Run. Simulated time = avr->cycle / F_CPU. Every slice (0.5 ms simulated) the board
  // talks to the pty, persists the EEPROM and, in real time, waits for the wall clock. ----
  const uint64_t f = avr->frequency;
  const uint64_t slice = f / 2000;
  const auto at = [f](double s) { return s < 0 ? ~0ull : static_cast<uint64_t>(s * f); };
  const uint64_t disconnect_at = at(common.disconnect_after_s);
  uint64_t stop_at = at(opt.seconds);
  const uint64_t measure_at = at(opt.measure_from_s);
  bool measuring = measure_at == 0;
  board::Cable cable(pty, common.link, common.reconnect_after_s);
  // The measurement window: [acc.start_cycle(), window_end); --measure-seconds closes it.
  uint64_t window_end = ~0ull, window_cycles = 0;
  bool window_closed = false;
  Accounting window_acc;
  ja_sim_bus_counters bus0{}, bus1{};
  uint64_t tx_seen = 0, tx_cycle = 0;
  bool ran_fast = false;
  uint64_t next_slice = 0, wall_start = MonotonicNs(), slices = 0;
  int state = cpu_Running, exit_code = 0;
  // JA_AVR_PROFILE=FILE (README "Profile"): awake cycles by (pc, activity id) inside the
  // measurement window, one `pc_hex id cycles` line each, written at exit.
  const char* prof_path = std::getenv("JA_AVR_PROFILE");
  std::unordered_map<uint64_t, uint64_t> prof;
  while (!g_stop) {
    const uint32_t pc0 = avr->pc;
    const uint8_t id0 = g_board.acc.current();
    const uint64_t c0 = avr->cycle, s0 = g_board.acc.sleep_cycles();
    state = avr_run(avr);
    if (prof_path && measuring && !window_closed) {
      prof[(uint64_t(pc0) << 8) | id0] += (avr->cycle - c0) - (g_board.acc.sleep_cycles() - s0);
    }
    if (state == cpu_Done || state == cpu_Crashed) break;
    uart.Service();
    twi_timing.Service();
    if (avr->cycle < next_slice) continue;
    next_slice = avr->cycle + slice;
    if ((!measuring && avr->cycle >= measure_at) || g_measure) {
      // The window opens (--measure-from, or SIGUSR1); --measure-seconds closes it and ends
      // the run.
      measuring = true;
      g_measure = 0;
      g_board.acc.Restart(avr->cycle);
      ja_sim_get_bus_counters(sim, &bus0, sizeof bus0);
      if (opt.measure_seconds >= 0) window_end = avr->cycle + at(opt.measure_seconds);
    }
    if (measuring && !window_closed && avr->cycle >= window_end) {
      // The window closes: its figures are frozen now; the run goes on for a short tail so the
      // frames the image stamped inside the window (still in its transmit ring) reach the host.
      window_closed = true;
      g_board.acc.Flush(avr->cycle);
      window_acc = g_board.acc;
      window_cycles = avr->cycle - g_board.acc.start_cycle();
      ja_sim_get_bus_counters(sim, &bus1, sizeof bus1);
      stop_at = avr->cycle + at(kDrainTailS);
    }
    if (avr->cycle >= stop_at) break;
    uart.Receive();
    uart.Flush();
    board::ApplySensorFaults(sim, &common.faults, avr->cycle * 1000000000ull / f);
    if (++slices % 16 == 0) eeprom.Persist();
    if (!cable.pulled() && avr->cycle >= disconnect_at) uart.ArmCut(f / 1000);
    if (!cable.pulled() && uart.CutReady()) {
      // The cable comes out between frames (after the delimiter of the frame on the line, as on
      // the native board, whose clock stops between loops), once the host has read what was sent.
      cable.Pull([&] { uart.Flush(); }, &g_stop);
      uart.Disconnected();
    }
    if (!cable.Service()) {
      exit_code = 1;
      break;
    }
    // --fast runs ahead only while the image streams (as the native board, which asks its app;
    // here: the AVR sent a byte within the last 100 ms simulated, longer than a loop at 10 Hz).
    // Before the host starts the stream, and after it stops it, time passes in real time, so the
    // motion and scheduled faults are not used up before anyone watches.
    if (uart.tx_bytes() != tx_seen) tx_seen = uart.tx_bytes(), tx_cycle = avr->cycle;
    const bool run_fast = common.fast && tx_seen > 0 && avr->cycle - tx_cycle < f / 10;
    if (run_fast != ran_fast) {
      ran_fast = run_fast;
      if (!run_fast) wall_start = MonotonicNs() - avr->cycle * 1000000000ull / f;
    }
    if (run_fast) {
      // The host is behind: simulated time waits for it (nothing is lost).
      while (uart.Blocked() && pty.open() && !g_stop) {
        pollfd p{pty.master(), POLLOUT, 0};
        poll(&p, 1, 20);
        uart.Flush();
      }
      continue;
    }
    // Real time: wait until the wall clock reaches simulated time (a byte from the host or room
    // in the pty ends the wait early). More than 1 s behind (a stopped process): catch up.
    const uint64_t sim_ns = avr->cycle * 1000000000ull / f;
    uint64_t wall = MonotonicNs() - wall_start;
    if (wall > sim_ns + 1000000000ull) {
      wall_start = MonotonicNs() - sim_ns;
    } else if (sim_ns > wall) {
      pty.Wait(sim_ns - wall);
    }
  }
  if (state == cpu_Crashed) {
    std::fprintf(stderr, "ja_avr_board: the AVR crashed at pc 0x%05x, cycle %llu\n",
                 static_cast<unsigned>(avr->pc), static_cast<unsigned long long>(avr->cycle));
    exit_code = 1;
  }
  if (prof_path) {
    FILE* pf = std::fopen(prof_path, "w");
    if (pf == nullptr) {
      std::fprintf(stderr, "ja_avr_board: cannot write JA_AVR_PROFILE %s\n", prof_path);
      return 2;
    }
    for (const auto& kv : prof) {
      std::fprintf(pf, "%llx %u %llu\n", static_cast<unsigned long long>(kv.first >> 8),
                   static_cast<unsigned>(kv.first & 0xFF),
                   static_cast<unsigned long long>(kv.second));
    }
    std::fclose(pf);
  }
  uart.Flush();
  eeprom.Persist();
  if (!window_closed) {
    g_board.acc.Flush(avr->cycle);
    window_acc = g_board.acc;
    window_cycles = measuring ? avr->cycle - g_board.acc.start_cycle() : 0;
    ja_sim_get_bus_counters(sim, &bus1, sizeof bus1);
  }
  const double sim_s = double(avr->cycle) / double(f);
  std::fprintf(stderr,
               "ja_avr_board: %.3f s simulated, %llu resets, %llu bytes sent, %llu received, "
               "injected: %llu dropped %llu corrupted, bridge dropped %llu, TWI waits stretched "
               "%llu, EEPROM writes %llu\n",
               sim_s, static_cast<unsigned long long>(g_board.resets),
               static_cast<unsigned long long>(uart.tx_bytes()),
               static_cast<unsigned long long>(uart.rx_bytes()),
               static_cast<unsigned long long>(uart.dropped()),
               static_cast<unsigned long long>(uart.corrupted()),
               static_cast<unsigned long long>(uart.bridge_dropped()),
               static_cast<unsigned long long>(twi_timing.stretched()),
               static_cast<unsigned long long>(eeprom.writes()));
  if (!eeprom.ok()) std::fprintf(stderr, "ja_avr_board: EEPROM file writes failed\n");
  if (!opt.report.empty()) {
    ReportInfo info;
    info.elf = opt.elf;
    info.frequency_hz = avr->frequency;
    info.cycles = window_cycles;
    info.window_start_s = double(window_acc.start_cycle()) / double(f);
    info.flash_bytes = fw.flashsize;
    info.static_ram_bytes = fw.datasize + fw.bsssize;
    info.stack_peak_bytes = StackPeak(avr, static_end);
    info.resets = g_board.resets;
    info.uart_tx_bytes = uart.tx_bytes();
    info.uart_rx_bytes = uart.rx_bytes();
    info.bridge_dropped = uart.bridge_dropped();
    info.injected_dropped = uart.dropped();
    info.injected_corrupted = uart.corrupted();
    info.uart_baud = uart.baud();
    const ja_sim_bus_counters& bus = bus1;
    info.bus_scl_bits = bus.scl_bits - bus0.scl_bits;
    info.bus_starts = bus.starts + bus.repeated_starts - bus0.starts - bus0.repeated_starts;
    info.bus_bytes = bus.bytes_written + bus.bytes_read - bus0.bytes_written - bus0.bytes_read;
    info.bus_nacks = bus.address_nacks + bus.data_nacks - bus0.address_nacks - bus0.data_nacks;
    info.real_scl_hz = opt.real_scl_hz;
    FILE* out = std::fopen(opt.report.c_str(), "w");
    if (!out || std::fputs(ReportJson(window_acc, info).c_str(), out) < 0) {
      std::fprintf(stderr, "ja_avr_board: cannot write the report %s\n", opt.report.c_str());
      exit_code = 1;
    }
    if (out) std::fclose(out);
  }
  return exit_code;
}

}  // namespace
}  // namespace avrboard
}  // namespace ja

int main(int argc, char** argv) { return ja::avrboard::Run(argc, argv); }
