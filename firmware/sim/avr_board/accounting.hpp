// Loop accounting for the AVR virtual board (ja_avr_board): where the CPU cycles go, by the
// activity id the firmware writes to GPIOR1, how many are spent asleep, and the stack high-water
// mark by SRAM painting (the same method as firmware/sim/avr_cycles).
//
// Contract with the image (issue 6): the firmware writes an activity id to GPIOR1 (I/O 0x2A, data
// address 0x4A); ISRs save GPIOR1, write their own id and restore it on exit. Ids:
//   0 other/main, 1 TWI ISR, 2 USART ISRs, 3 filter step, 4 calibration/conversion,
//   5 framing/CRC/streaming, 6 timer ISR, 7 command handling (any other value is kept as is).
// On every write the cycles since the previous change are attributed to the previous id, minus
// the cycles the core slept in between (those are counted apart, as sleep):
//   active[id_prev] += (cycle_now - cycle_prev) - (sleep_now - sleep_prev).
// entries[id] counts ISR invocations and main-context changes to `id` (an ISR restoring the id it
// interrupted is not a new entry), so entries[3] is the number of filter steps ("loops").
// simavr adds an instruction's cycles after executing it, so inside the write callback
// avr->cycle is the count before the `out`; the `out` itself lands in the new id (1 cycle).
//
// Sleep: simavr calls avr->sleep(avr, n) when the core sleeps, then adds 1 + n to avr->cycle;
// the board's sleep hook calls AddSleep(1 + n).
#pragma once

#include <stdint.h>

#include <string>

struct avr_t;

namespace ja {
namespace avrboard {

constexpr int kActivityIds = 256;
constexpr uint16_t kActivityAddr = 0x4A;  // GPIOR1 (I/O 0x2A)
constexpr uint8_t kPaint = 0xA5;

/// The names of the contract's ids 0..7 (nullptr above).
const char* ActivityName(int id);
/// The ids interrupts write (1 TWI, 2 USART, 6 timer).
bool IsIsr(int id);

class Accounting {
 public:
  /// Starts counting at `cycle` (also used by --measure-from to restart the window).
  void Restart(uint64_t cycle);
  /// A write of `id` to GPIOR1 at `cycle`.
  void OnActivity(uint64_t cycle, uint8_t id);
  /// The core slept `cycles` (simavr's sleep callback: 1 + howLong).
  void AddSleep(uint64_t cycles) { sleep_ += cycles; }
  /// Closes the open interval at `cycle` (before a report).
  void Flush(uint64_t cycle);

  uint64_t start_cycle() const { return start_; }
  uint64_t sleep_cycles() const { return sleep_ - sleep_at_start_; }
  uint64_t active(int id) const { return active_[id]; }
  uint64_t entries(int id) const { return entries_[id]; }
  uint8_t current() const { return id_; }

 private:
  uint64_t active_[kActivityIds] = {};
  uint64_t entries_[kActivityIds] = {};
  uint8_t id_ = 0;
  uint64_t last_cycle_ = 0, last_sleep_ = 0, sleep_ = 0, start_ = 0, sleep_at_start_ = 0;
};

/// Paints SRAM from the end of .data+.bss to RAMEND with kPaint (before the first instruction).
void PaintStack(avr_t* avr, uint32_t static_end);
/// Bytes from RAMEND down to the lowest byte that is no longer kPaint (deepest stack use).
uint32_t StackPeak(const avr_t* avr, uint32_t static_end);

/// Everything the --report JSON holds besides the accounting (filled by the board).
struct ReportInfo {
  std::string elf;
  uint32_t frequency_hz = 0;
  uint64_t cycles = 0;        // in the measurement window
  double window_start_s = 0;  // simulated time the window opened
  uint32_t flash_bytes = 0, static_ram_bytes = 0, stack_peak_bytes = 0;
  uint64_t resets = 0, uart_tx_bytes = 0, uart_rx_bytes = 0, bridge_dropped = 0,
           injected_dropped = 0, injected_corrupted = 0;
  double uart_baud = 0;
  // Bus (ja_sim_bus_counters, over the window): SCL periods = 9 per byte + 1 per START/Sr/STOP.
  uint64_t bus_scl_bits = 0, bus_starts = 0, bus_bytes = 0, bus_nacks = 0;
  double real_scl_hz = 400000.0;
};

/// The report as one JSON object (see README.md).
std::string ReportJson(const Accounting& acc, const ReportInfo& info);

}  // namespace avrboard
}  // namespace ja
