// Real I2C bus timing for simavr 1.6's TWI. simavr 1.6 ignores TWBR and raises TWINT a fixed
// 9 us after every address or data byte (START: at once; docs/sensors.md §D2), so a simulated bus
// runs at about 1 MHz. This stretches each of those waits to the byte's real duration at the rig's
// SCL rate: 9 SCL periods (8 bits + ACK), i.e. 9 * F_CPU / f_SCL cycles (360 cycles at 16 MHz and
// 400 kHz, 22.5 us). START/repeated START (simavr: no wait) and STOP stay untimed: about one SCL
// period per condition (~1 % of a 6-byte register read, 84 SCL periods) is not modelled.
//
// How: the TWI module schedules avr_twi_set_state_timer(param = the TWI) right after raising the
// byte on TWI_IRQ_OUTPUT; after that instruction the board moves the pending timer to
// byte-start + 9 SCL periods (cancel, then register again with the same callback and param).
// SLA+W gets no wait in 1.6 (TWINT is up at once): the board clears the TWI interrupt and raises
// it again when the byte would have ended.
//
// Clock stretching (optional, per address): a slave that holds SCL low before it answers a read
// (the BNO055 does, for hundreds of us at times; docs/sensors.md §A3) makes the master wait that
// much longer after SLA+R; SetStretch adds it to that byte's wait.
#pragma once

#include <stdint.h>

struct avr_t;
struct avr_irq_t;

namespace ja {
namespace avrboard {

class TwiTiming {
 public:
  /// Hooks TWI 0; false if the core has none. scl_hz 0: keep simavr's own timing.
  bool Attach(avr_t* avr, uint32_t scl_hz);
  /// After every instruction: stretch the wait a byte event scheduled.
  void Service() {
    if (pending_) Stretch();
  }
  uint64_t stretched() const { return stretched_; }
  /// Clock stretching: `us` microseconds more after every SLA+R to `addr7` (0: none).
  void SetStretch(uint8_t addr7, uint32_t us);

 private:
  static void OnOutput(avr_irq_t* irq, uint32_t value, void* param);
  static uint64_t RaiseLater(avr_t* avr, uint64_t when, void* param);
  void Stretch();

  avr_t* avr_ = nullptr;
  void* twi_ = nullptr;
  uint64_t byte_cycles_ = 0, event_cycle_ = 0, stretched_ = 0;
  uint64_t extra_cycles_ = 0;      // this byte's clock stretching
  uint32_t stretch_us_[128] = {};  // per 7-bit address
  bool pending_ = false;
};

}  // namespace avrboard
}  // namespace ja
