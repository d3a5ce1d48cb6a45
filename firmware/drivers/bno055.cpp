#include "drivers/bno055.hpp"

namespace ja {
namespace drivers {

DeviceStatus Bno055::Configure(const bno055::Settings& s) {
  using namespace bno055;
  uint8_t id = 0;
  if (WriteRegister(bus_, addr7_, kRegPageId, 0) != I2cStatus::kOk ||
      ReadRegister(bus_, addr7_, kRegChipId, &id) != I2cStatus::kOk) {
    return DeviceStatus::kBusFault;
  }
  if (id != kChipId) return DeviceStatus::kWrongId;
  if (WriteRegister(bus_, addr7_, kRegOprMode, kModeConfig) != I2cStatus::kOk) {
    return DeviceStatus::kBusFault;
  }
  delay_.WaitMs(kToConfigMs);
  const uint8_t acc_config = AccConfigValue(s);
  uint8_t back = 0;
  if (WriteRegister(bus_, addr7_, kRegPageId, 1) != I2cStatus::kOk ||
      WriteRegister(bus_, addr7_, kRegAccConfig, acc_config) != I2cStatus::kOk ||
      ReadRegister(bus_, addr7_, kRegAccConfig, &back) != I2cStatus::kOk ||
      WriteRegister(bus_, addr7_, kRegPageId, 0) != I2cStatus::kOk) {
    return DeviceStatus::kBusFault;
  }
  if (back != acc_config) return DeviceStatus::kVerifyFailed;
  if (WriteRegister(bus_, addr7_, kRegUnitSel, kUnitsMps2) != I2cStatus::kOk ||
      WriteRegister(bus_, addr7_, kRegOprMode, kModeAccOnly) != I2cStatus::kOk) {
    return DeviceStatus::kBusFault;
  }
  delay_.WaitMs(kToOperatingMs);
  has_last_ = false;
  repeats_are_stale_ = s.read_rate_hz == 0 || s.read_rate_hz > AccOdrHz(s.bandwidth);
  return DeviceStatus::kOk;
}

DeviceStatus Bno055::ReadSample(RawSample* out) {
  uint8_t b[bno055::kAccDataBytes];
  if (bus_.Read(addr7_, bno055::kRegAccDataXLsb, b, sizeof b) != I2cStatus::kOk) {
    return DeviceStatus::kBusFault;
  }
  const RawSample s = bno055::DecodeSample(b);
  const bool same = has_last_ && s.x == last_.x && s.y == last_.y && s.z == last_.z;
  last_ = s;
  has_last_ = true;
  if (same && repeats_are_stale_) return DeviceStatus::kNotReady;
  *out = s;
  ++fresh_count_;
  return DeviceStatus::kOk;
}

}  // namespace drivers
}  // namespace ja
