// Virtual TCA9548A 1-to-8 I2C multiplexer (docs/sensors.md §A4, TI SCPS207F): one control register
// and no register pointer. Every written byte replaces the control register (the last byte of a
// multi-byte write is kept); every read byte returns it; bit n connects downstream channel n.
// A new selection takes effect at the STOP that ends the write. Power-up and /RESET: 0x00.
#pragma once

#include <stdint.h>

#include "sim/devices/i2c_target.hpp"

namespace ja {
namespace sim {

class Tca9548a final : public I2cTarget {
 public:
  static constexpr uint8_t kBaseAddress = 0x70;  // 0x70 | A2A1A0
  static constexpr uint8_t kChannels = 8;

  explicit Tca9548a(uint8_t addr7 = kBaseAddress) : I2cTarget(addr7) {}
  const char* model() const override { return "tca9548a"; }
  void PowerOnReset() override;
  /// The /RESET pin pulled low: control register cleared, every channel disconnected.
  void PulseReset() { PowerOnReset(); }
  bool SupportsFault(FaultKind kind) const override;

  /// Control register as written (what a read returns).
  uint8_t control() const { return control_; }
  /// Channels connected now (the control register as of the last STOP).
  uint8_t connected() const { return connected_; }

 protected:
  bool OnWrite(uint8_t byte, bool first) override;
  uint8_t OnRead() override;
  void OnStop() override;

 private:
  uint8_t control_ = 0;
  uint8_t connected_ = 0;
};

}  // namespace sim
}  // namespace ja
