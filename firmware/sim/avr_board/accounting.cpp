#include "sim/avr_board/accounting.hpp"

#include <inttypes.h>
#include <sim_avr.h>

#include <cstdio>
#include <sstream>

namespace ja {
namespace avrboard {

const char* ActivityName(int id) {
  static const char* const kNames[] = {"main",        "twi_isr",   "usart_isr", "filter",
                                       "calibration", "streaming", "timer_isr", "commands"};
  return id >= 0 && id < 8 ? kNames[id] : nullptr;
}

bool IsIsr(int id) { return id == 1 || id == 2 || id == 6; }

void Accounting::Restart(uint64_t cycle) {
  for (int i = 0; i < kActivityIds; ++i) active_[i] = entries_[i] = 0;
  start_ = last_cycle_ = cycle;
  sleep_at_start_ = last_sleep_ = sleep_;
}

void Accounting::OnActivity(uint64_t cycle, uint8_t id) {
  Flush(cycle);
  // An entry is an ISR invocation, or a main-context change of activity; an ISR restoring the
  // id it interrupted is no new entry (so entries into the filter id count filter steps).
  if (id != id_ && (IsIsr(id) || !IsIsr(id_))) ++entries_[id];
  id_ = id;
}

void Accounting::Flush(uint64_t cycle) {
  const uint64_t slept = sleep_ - last_sleep_;
  const uint64_t span = cycle - last_cycle_;
  active_[id_] += span > slept ? span - slept : 0;
  last_cycle_ = cycle;
  last_sleep_ = sleep_;
}

void PaintStack(avr_t* avr, uint32_t static_end) {
  for (uint32_t a = static_end; a <= avr->ramend; ++a) avr->data[a] = kPaint;
}

uint32_t StackPeak(const avr_t* avr, uint32_t static_end) {
  uint32_t lowest = avr->ramend + 1u;
  for (uint32_t a = static_end; a <= avr->ramend; ++a) {
    if (avr->data[a] != kPaint) {
      lowest = a;
      break;
    }
  }
  return avr->ramend + 1u - lowest;
}

std::string ReportJson(const Accounting& acc, const ReportInfo& info) {
  // Loops = entries into the filter step (id 3); the split is per loop. Bus time at a real
  // SCL rate: t_bus = scl_bits / f_SCL; occupancy = t_bus / simulated time of the window.
  const double seconds = info.frequency_hz ? double(info.cycles) / info.frequency_hz : 0.0;
  const uint64_t loops = acc.entries(3);
  const double bus_s = double(info.bus_scl_bits) / info.real_scl_hz;
  std::ostringstream o;
  char buf[256];
  o << "{\"elf\": \"";
  for (char c : info.elf) {
    if (c == '"' || c == '\\') o << '\\';
    o << c;
  }
  std::snprintf(buf, sizeof buf,
                "\", \"frequency_hz\": %" PRIu32 ", \"window_start_s\": %.6f, \"cycles\": %" PRIu64
                ", \"seconds\": %.6f, \"sleep_cycles\": %" PRIu64 ", \"idle_fraction\": %.6f",
                info.frequency_hz, info.window_start_s, info.cycles, seconds, acc.sleep_cycles(),
                info.cycles ? double(acc.sleep_cycles()) / double(info.cycles) : 0.0);
  o << buf;
  std::snprintf(buf, sizeof buf,
                ", \"loops\": %" PRIu64 ", \"loop_rate_hz\": %.3f, \"flash_bytes\": %" PRIu32
                ", \"static_ram_bytes\": %" PRIu32 ", \"stack_peak_bytes\": %" PRIu32,
                loops, seconds > 0 ? double(loops) / seconds : 0.0, info.flash_bytes,
                info.static_ram_bytes, info.stack_peak_bytes);
  o << buf;
  std::snprintf(buf, sizeof buf,
                ", \"resets\": %" PRIu64 ", \"uart\": {\"baud\": %.0f, \"tx_bytes\": %" PRIu64
                ", \"rx_bytes\": %" PRIu64 ", \"bridge_dropped\": %" PRIu64
                ", \"injected_dropped\": %" PRIu64 ", \"injected_corrupted\": %" PRIu64 "}",
                info.resets, info.uart_baud, info.uart_tx_bytes, info.uart_rx_bytes,
                info.bridge_dropped, info.injected_dropped, info.injected_corrupted);
  o << buf;
  std::snprintf(buf, sizeof buf,
                ", \"bus\": {\"scl_bits\": %" PRIu64 ", \"starts\": %" PRIu64
                ", \"bytes\": %" PRIu64 ", \"nacks\": %" PRIu64
                ", \"real_scl_hz\": %.0f, \"busy_s\": %.6f, \"occupancy\": %.6f}",
                info.bus_scl_bits, info.bus_starts, info.bus_bytes, info.bus_nacks,
                info.real_scl_hz, bus_s, seconds > 0 ? bus_s / seconds : 0.0);
  o << buf << ", \"activity\": {";
  bool first = true;
  for (int id = 0; id < kActivityIds; ++id) {
    if (!acc.active(id) && !acc.entries(id)) continue;
    const char* name = ActivityName(id);
    std::snprintf(buf, sizeof buf,
                  "%s\"%d\": {\"name\": \"%s\", \"cycles\": %" PRIu64 ", \"entries\": %" PRIu64
                  ", \"per_loop\": %.1f}",
                  first ? "" : ", ", id, name ? name : "other", acc.active(id), acc.entries(id),
                  loops ? double(acc.active(id)) / double(loops) : 0.0);
    o << buf;
    first = false;
  }
  o << "}}\n";
  return o.str();
}

}  // namespace avrboard
}  // namespace ja
