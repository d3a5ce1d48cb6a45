// TCA9548A 1-to-8 I2C multiplexer (docs/sensors.md §A4): one control register, no register pointer;
// bit n enables downstream channel n; readable; power-up value 0.
//
// On the injected bus, the control byte travels in the `reg` position: Write(addr, mask, -, 0)
// selects, and Read(addr, mask, &v, 1) selects then reads the control register back in the same
// transaction (write mask, repeated START, read 1 byte) - the read-back check costs one byte.
#pragma once

#include <stdint.h>

#include "drivers/i2c_bus.hpp"

namespace ja {
namespace drivers {
namespace tca9548a {
constexpr uint8_t kBaseAddress = 0x70;  // 0x70 | A2A1A0
constexpr uint8_t kChannels = 8;
constexpr uint8_t kNone = 0x00;  // control value: every channel off
}  // namespace tca9548a

/// The multiplexer itself: remembers the selected channel so repeated accesses on one channel
/// cost no extra select.
class Tca9548a {
 public:
  Tca9548a(I2cBus& upstream, uint8_t addr7) : upstream_(upstream), addr7_(addr7) {}

  /// Enables exactly `channel` (0..7) and checks the read-back. kVerifyFailed if the device
  /// answered with another value; the cached selection is then forgotten.
  DeviceStatus Select(uint8_t channel);
  /// Disconnects every channel.
  DeviceStatus Deselect();
  /// Disconnects every channel unless that is known to be so already. A multiplexer that does
  /// not answer passes no channel either: that counts as disconnected (a rig without one).
  void EnsureNoneSelected();
  /// Forget the cached selection (e.g. after a bus reset), forcing the next Select to talk.
  void Invalidate() { selected_ = kUnknown; }

  I2cBus& upstream() { return upstream_; }
  uint8_t address() const { return addr7_; }
  uint16_t select_count() const { return select_count_; }

 private:
  static constexpr uint8_t kUnknown = 0xFF;
  I2cBus& upstream_;
  uint8_t addr7_;
  uint8_t selected_ = kUnknown;  // channel number, 8 = none, kUnknown
  uint16_t select_count_ = 0;    // transactions spent selecting (bus occupancy accounting)
};

/// A downstream channel of the multiplexer as an I2cBus (decorator): selects, then forwards.
class Tca9548aChannel final : public I2cBus {
 public:
  Tca9548aChannel(Tca9548a& mux, uint8_t channel) : mux_(mux), channel_(channel) {}
  I2cStatus Read(uint8_t addr7, uint8_t reg, uint8_t* buf, uint8_t n) override;
  I2cStatus Write(uint8_t addr7, uint8_t reg, const uint8_t* buf, uint8_t n) override;
  uint8_t channel() const { return channel_; }

 private:
  Tca9548a& mux_;
  uint8_t channel_;
};

/// The upstream bus with every channel of the multiplexer off (decorator): a sensor wired to the
/// bus directly is never read while a channel holding a part at the same address is connected.
class Tca9548aRoot final : public I2cBus {
 public:
  explicit Tca9548aRoot(Tca9548a& mux) : mux_(mux) {}
  I2cStatus Read(uint8_t addr7, uint8_t reg, uint8_t* buf, uint8_t n) override;
  I2cStatus Write(uint8_t addr7, uint8_t reg, const uint8_t* buf, uint8_t n) override;

 private:
  Tca9548a& mux_;
};

}  // namespace drivers
}  // namespace ja
