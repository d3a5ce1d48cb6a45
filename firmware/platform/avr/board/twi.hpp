// TWI0 master at 400 kHz (TWBR = 12, prescaler 1: 16e6 / (16 + 2 * 12) = 400 kHz), driven by
// its interrupt. One engine serves both views the app needs (app/hal.hpp):
// - I2cBatch: the steady-state sample reads; Start() returns at once and the TWI interrupt
//   walks the transfer list (select, read, STOP, next START ...) while the CPU filters;
// - drivers::I2cBus: probing and configuration; each call waits (asleep) for the batch in
//   flight, then runs its one transaction on the same engine and waits (asleep) for it.
// A transfer that does not finish in time (stuck bus, endless clock stretching) is aborted:
// the TWI is reset and the transfer reports kTimeout.
//
// simavr 1.6 quirks (docs/sensors.md §D2), tolerated without changing what real silicon does: SLA+W
// ACK arrives as status 0x28 (not 0x18) and its NACK as 0x30 (not 0x20) - the engine tracks
// its own phase, so "data ACK" right after SLA+W means "address ACKed"; writing TWINT never
// clears it in 1.6, which only matters to polling drivers (this one waits for the interrupt).
#pragma once

#include <stdint.h>

#include "app/hal.hpp"
#include "drivers/i2c_bus.hpp"

namespace ja {
namespace avr {

class Twi final : public drivers::I2cBus, public app::I2cBatch {
 public:
  static constexpr uint8_t kTwbr = 12;  // 400 kHz at 16 MHz, prescaler 1
  static constexpr uint32_t kTransferTimeoutUs = 5000;
  static constexpr uint32_t kBatchTimeoutUs = 20000;

  /// Pins, bit rate, enable. Call once with interrupts off.
  void Init();

  drivers::I2cStatus Read(uint8_t addr7, uint8_t reg, uint8_t* buf, uint8_t n) override;
  drivers::I2cStatus Write(uint8_t addr7, uint8_t reg, const uint8_t* buf, uint8_t n) override;

  void Start(app::I2cTransfer* t, uint8_t count) override;
  void Wait() override;

  bool busy() const;
  uint16_t timeouts() const { return timeouts_; }

 private:
  /// Waits (asleep) until the engine is idle; on timeout aborts it. True if it finished.
  bool WaitIdle(uint32_t timeout_us);
  /// Starts the list on the idle engine (Start: a batch; Read/Write: their one transfer, with
  /// g_wbuf / g_wn set for a write's data).
  void Run(app::I2cTransfer* t, uint8_t count);
  uint16_t timeouts_ = 0;
};

Twi& SystemTwi();

}  // namespace avr
}  // namespace ja
