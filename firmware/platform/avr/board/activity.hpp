// What the CPU works on, for the loop budget (issue 6 contract with the simavr board): the id
// (app/hal.hpp `activity::`) goes to GPIOR1 (I/O 0x2A, data 0x4A); the harness sums cycles per
// id and counts sleep apart. Interrupts save the interrupted id, write theirs and restore it.
// GPIOR0 / GPIOR2 stay the region markers and console of cycle_marker.hpp.
#pragma once

#include <avr/io.h>
#include <stdint.h>

namespace ja {
namespace avr {

/// Main-context activity change. The memory clobbers keep work from moving across the mark.
inline void SetActivity(uint8_t id) {
  asm volatile("" ::: "memory");
  GPIOR1 = id;
  asm volatile("" ::: "memory");
}

/// In an ISR: `IsrActivity a(id);` first thing; the interrupted id is back when it returns.
class IsrActivity {
 public:
  explicit IsrActivity(uint8_t id) : saved_(GPIOR1) { GPIOR1 = id; }
  ~IsrActivity() { GPIOR1 = saved_; }
  IsrActivity(const IsrActivity&) = delete;
  IsrActivity& operator=(const IsrActivity&) = delete;

 private:
  uint8_t saved_;
};

}  // namespace avr
}  // namespace ja
