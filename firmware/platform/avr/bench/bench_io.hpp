// Bench I/O for bench_numerics and bench_filter: on AVR, cycle regions and console go to the
// simavr harness (firmware/sim/avr_cycles) through GPIO registers; on the Pico (Cortex-M0+) to
// the emulator's (firmware/sim/pico_board/pico_cycles.mjs) through breakpoints; on x86 regions
// are no-ops and the console is stdout, so the same program prints the same check lines on all.
#pragma once
#include <stdint.h>

#if defined(__AVR__)
#include "platform/avr/cycle_marker.hpp"
namespace bench {
inline void Begin(uint8_t id) { ja::avr::BeginRegion(id); }
inline void End() { ja::avr::EndRegion(); }
inline void Print(const char* s) { ja::avr::ConsolePrint(s); }
inline void PrintInt(int32_t v) { ja::avr::ConsolePrintInt(v); }
[[noreturn]] inline void Finish() { ja::avr::StopSimulation(); }
}  // namespace bench
#elif defined(__arm__)
#include "platform/pico/bench/cycle_marker.hpp"
namespace bench {
inline void Begin(uint8_t id) { ja::pico::BeginRegion(id); }
inline void End() { ja::pico::EndRegion(); }
inline void Print(const char* s) { ja::pico::ConsolePrint(s); }
inline void PrintInt(int32_t v) { ja::pico::ConsolePrintInt(v); }
[[noreturn]] inline void Finish() { ja::pico::StopSimulation(); }
}  // namespace bench
#else
#include <cstdio>
#include <cstdlib>
namespace bench {
inline void Name(uint8_t, const char*) {}
inline void Begin(uint8_t) {}
inline void End() {}
inline void Print(const char* s) { std::fputs(s, stdout); }
inline void PrintInt(int32_t v) { std::printf("%ld", static_cast<long>(v)); }
[[noreturn]] inline void Finish() {
  std::fflush(stdout);
  std::exit(0);
}
}  // namespace bench
#endif

#if defined(__AVR__) || defined(__arm__)
namespace bench {
/// Names region `id` for the cycle harness's report: a console line "@region <id> <name>".
inline void Name(uint8_t id, const char* name) {
  Print("@region ");
  PrintInt(id);
  Print(" ");
  Print(name);
  Print("\n");
}
}  // namespace bench
#endif
