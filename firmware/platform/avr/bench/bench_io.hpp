// Bench I/O for bench_numerics: on AVR, cycle regions and console go to the simavr harness
// (firmware/sim/avr_cycles) through GPIO registers; on x86 regions are no-ops and the console is
// stdout, so the same program prints the same check lines on both.
#pragma once
#include <stdint.h>

#if defined(__AVR__)
#include "platform/avr/cycle_marker.hpp"
namespace bench {
inline void Name(uint8_t id, const char* name) { ja::avr::NameRegion(id, name); }
inline void Begin(uint8_t id) { ja::avr::BeginRegion(id); }
inline void End() { ja::avr::EndRegion(); }
inline void Print(const char* s) { ja::avr::ConsolePrint(s); }
inline void PrintInt(int32_t v) { ja::avr::ConsolePrintInt(v); }
[[noreturn]] inline void Finish() { ja::avr::StopSimulation(); }
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
