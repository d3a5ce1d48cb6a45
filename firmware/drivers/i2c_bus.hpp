// The injected bus every driver talks to (docs/design.md §2): register reads and writes on a
// 7-bit address, nothing else. Implementations: the AVR TWI driver, the Linux smbus adapter,
// the virtual devices, the TCA9548A channel decorator and the tests' recording fake.
#pragma once

#include <stdint.h>

namespace ja {
namespace drivers {

enum class I2cStatus : uint8_t {
  kOk = 0,
  kNack,      // address or data not acknowledged
  kBusError,  // arbitration lost, illegal START/STOP, stuck bus
  kTimeout,
};

class I2cBus {
 public:
  /// Writes `reg`, then (repeated START) reads `n` bytes into `buf`.
  virtual I2cStatus Read(uint8_t addr7, uint8_t reg, uint8_t* buf, uint8_t n) = 0;
  /// Writes `reg` followed by `n` bytes of `buf` in one transaction (n may be 0).
  virtual I2cStatus Write(uint8_t addr7, uint8_t reg, const uint8_t* buf, uint8_t n) = 0;

 protected:
  ~I2cBus() = default;
};

/// Blocking millisecond delay, injected so drivers never read a clock themselves.
class Delay {
 public:
  virtual void WaitMs(uint16_t ms) = 0;

 protected:
  ~Delay() = default;
};

/// Driver outcome; also the per-sensor fault cause the application reports.
enum class DeviceStatus : uint8_t {
  kOk = 0,
  kBusFault,      // the bus returned an error (NACK, bus error, timeout)
  kWrongId,       // identification register mismatch: wrong or absent part
  kVerifyFailed,  // a read-back did not match what was written
  kNotReady,      // no new sample since the last read
};

inline DeviceStatus ToDeviceStatus(I2cStatus s) {
  return s == I2cStatus::kOk ? DeviceStatus::kOk : DeviceStatus::kBusFault;
}

/// One accelerometer sample in the sensor's counts, sensor frame (x, y, z).
struct RawSample {
  int32_t x = 0, y = 0, z = 0;
};

/// Writes one byte to a register.
inline I2cStatus WriteRegister(I2cBus& bus, uint8_t addr7, uint8_t reg, uint8_t value) {
  return bus.Write(addr7, reg, &value, 1);
}

/// Reads one byte from a register.
inline I2cStatus ReadRegister(I2cBus& bus, uint8_t addr7, uint8_t reg, uint8_t* value) {
  return bus.Read(addr7, reg, value, 1);
}

}  // namespace drivers
}  // namespace ja
