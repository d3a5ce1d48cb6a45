#include "drivers/tca9548a.hpp"

namespace ja {
namespace drivers {

DeviceStatus Tca9548a::Select(uint8_t channel) {
  if (channel >= tca9548a::kChannels) return DeviceStatus::kVerifyFailed;
  if (selected_ == channel) return DeviceStatus::kOk;
  const uint8_t mask = static_cast<uint8_t>(1u << channel);
  uint8_t readback = 0;
  ++select_count_;
  // Write the control byte, then read it back (same transaction, repeated START).
  const I2cStatus s = upstream_.Read(addr7_, mask, &readback, 1);
  if (s != I2cStatus::kOk) {
    selected_ = kUnknown;
    return DeviceStatus::kBusFault;
  }
  if (readback != mask) {
    selected_ = kUnknown;
    return DeviceStatus::kVerifyFailed;
  }
  selected_ = channel;
  return DeviceStatus::kOk;
}

DeviceStatus Tca9548a::Deselect() {
  ++select_count_;
  const I2cStatus s = upstream_.Write(addr7_, tca9548a::kNone, nullptr, 0);
  selected_ = s == I2cStatus::kOk ? tca9548a::kChannels : kUnknown;
  return ToDeviceStatus(s);
}

void Tca9548a::EnsureNoneSelected() {
  if (selected_ == tca9548a::kChannels) return;
  if (Deselect() != DeviceStatus::kOk) selected_ = tca9548a::kChannels;  // nobody answered
}

I2cStatus Tca9548aRoot::Read(uint8_t addr7, uint8_t reg, uint8_t* buf, uint8_t n) {
  mux_.EnsureNoneSelected();
  return mux_.upstream().Read(addr7, reg, buf, n);
}

I2cStatus Tca9548aRoot::Write(uint8_t addr7, uint8_t reg, const uint8_t* buf, uint8_t n) {
  mux_.EnsureNoneSelected();
  return mux_.upstream().Write(addr7, reg, buf, n);
}

I2cStatus Tca9548aChannel::Read(uint8_t addr7, uint8_t reg, uint8_t* buf, uint8_t n) {
  const DeviceStatus s = mux_.Select(channel_);
  if (s != DeviceStatus::kOk) return I2cStatus::kBusError;
  return mux_.upstream().Read(addr7, reg, buf, n);
}

I2cStatus Tca9548aChannel::Write(uint8_t addr7, uint8_t reg, const uint8_t* buf, uint8_t n) {
  const DeviceStatus s = mux_.Select(channel_);
  if (s != DeviceStatus::kOk) return I2cStatus::kBusError;
  return mux_.upstream().Write(addr7, reg, buf, n);
}

}  // namespace drivers
}  // namespace ja
