// TWSR as an ATmega2560 reports it, for every client (issue 22 item 4). simavr 1.6 reports the
// outcome of SLA+W as if it were a data byte: 0x28 for an acknowledged address (a real TWI says
// 0x18) and 0x30 for an absent one (0x20), so Arduino's Wire returns 3 (data NACK) instead of 2
// (address NACK) from endTransmission() (docs/sensors.md §D2). The board watches the TWI's bus
// events and, when the status that follows an SLA+W is set, writes the datasheet's code in its
// place before the interrupt is taken. SLA+R (0x40/0x48) and data bytes are reported correctly
// already and are left alone; on a simavr that reports 0x18/0x20 itself nothing changes.
#pragma once

#include <stdint.h>

struct avr_t;
struct avr_irq_t;

namespace ja {
namespace avrboard {

class TwiStatus {
 public:
  /// Hooks TWI 0; false if the core has none.
  bool Attach(avr_t* avr);
  /// How many statuses were corrected.
  uint64_t corrected() const { return corrected_; }

 private:
  static void OnOutput(avr_irq_t* irq, uint32_t value, void* param);
  static void OnStatus(avr_irq_t* irq, uint32_t value, void* param);

  avr_t* avr_ = nullptr;
  void* twi_ = nullptr;
  bool after_sla_w_ = false;  // the next status is SLA+W's
  uint64_t corrected_ = 0;
};

}  // namespace avrboard
}  // namespace ja
