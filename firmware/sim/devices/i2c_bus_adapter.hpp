// The firmware drivers' injected bus (drivers/i2c_bus.hpp) over the virtual bus: what the
// native virtual board and the driver-agreement tests plug the drivers into. Register reads
// are write(reg), repeated START, read(n), STOP; writes are one transaction (reg, data...).
// The TCA9548A decorator's control byte travels in `reg`, which is exactly its wire format.
#pragma once

#include <stdint.h>

#include "drivers/i2c_bus.hpp"
#include "sim/devices/bus.hpp"

namespace ja {
namespace sim {

inline drivers::I2cStatus ToDriverStatus(I2cResult r) {
  switch (r) {
    case I2cResult::kOk:
      return drivers::I2cStatus::kOk;
    case I2cResult::kAddressNack:
    case I2cResult::kDataNack:
      return drivers::I2cStatus::kNack;
    default:
      return drivers::I2cStatus::kBusError;
  }
}

class DriverBusAdapter final : public drivers::I2cBus {
 public:
  explicit DriverBusAdapter(Bus& bus) : bus_(bus) {}
  drivers::I2cStatus Read(uint8_t addr7, uint8_t reg, uint8_t* buf, uint8_t n) override {
    return ToDriverStatus(bus_.WriteRead(addr7, &reg, 1, buf, n));
  }
  drivers::I2cStatus Write(uint8_t addr7, uint8_t reg, const uint8_t* buf, uint8_t n) override {
    uint8_t frame[256];
    frame[0] = reg;
    for (uint8_t i = 0; i < n && i < 255; ++i) frame[i + 1] = buf[i];
    return ToDriverStatus(bus_.Write(addr7, frame, static_cast<size_t>(n) + 1u));
  }

 private:
  Bus& bus_;
};

/// The drivers' Delay as simulated time: waiting advances device time.
class SimDelay final : public drivers::Delay {
 public:
  explicit SimDelay(Bus& bus) : bus_(bus) {}
  void WaitMs(uint16_t ms) override { bus_.SetTimeNs(bus_.time_ns() + ms * 1000000ull); }

 private:
  Bus& bus_;
};

}  // namespace sim
}  // namespace ja
