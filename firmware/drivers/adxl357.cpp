#include "drivers/adxl357.hpp"

namespace ja {
namespace drivers {

DeviceStatus Adxl357::Configure(const adxl357::Settings& s) {
  using namespace adxl357;
  uint8_t id[3] = {0, 0, 0};
  I2cStatus st = bus_.Read(addr7_, kRegDevIdAd, id, sizeof id);
  if (st != I2cStatus::kOk) return DeviceStatus::kBusFault;
  if (id[0] != kDevIdAd || id[1] != kDevIdMst || id[2] != kPartId) return DeviceStatus::kWrongId;
  // Range and ODR may only change in standby.
  st = WriteRegister(bus_, addr7_, kRegPowerCtl, kPowerStandby);
  if (st != I2cStatus::kOk) return DeviceStatus::kBusFault;
  uint8_t range = 0, filter = 0;
  if (ReadRegister(bus_, addr7_, kRegRange, &range) != I2cStatus::kOk ||
      ReadRegister(bus_, addr7_, kRegFilter, &filter) != I2cStatus::kOk) {
    return DeviceStatus::kBusFault;
  }
  range = static_cast<uint8_t>((range & ~kRangeMask) | static_cast<uint8_t>(s.range));
  filter = static_cast<uint8_t>((filter & ~kOdrMask) | static_cast<uint8_t>(s.odr));
  if (WriteRegister(bus_, addr7_, kRegRange, range) != I2cStatus::kOk ||
      WriteRegister(bus_, addr7_, kRegFilter, filter) != I2cStatus::kOk) {
    return DeviceStatus::kBusFault;
  }
  uint8_t range_back = 0, filter_back = 0;
  if (ReadRegister(bus_, addr7_, kRegRange, &range_back) != I2cStatus::kOk ||
      ReadRegister(bus_, addr7_, kRegFilter, &filter_back) != I2cStatus::kOk) {
    return DeviceStatus::kBusFault;
  }
  if (range_back != range || filter_back != filter) return DeviceStatus::kVerifyFailed;
  st = WriteRegister(bus_, addr7_, kRegPowerCtl, kPowerMeasure);
  return ToDeviceStatus(st);
}

DeviceStatus Adxl357::ReadSample(RawSample* out) {
  // STATUS, FIFO_ENTRIES, TEMP2, TEMP1, then the 9 data bytes.
  uint8_t b[13];
  const I2cStatus st = bus_.Read(addr7_, adxl357::kRegStatus, b, sizeof b);
  if (st != I2cStatus::kOk) return DeviceStatus::kBusFault;
  if (!(b[0] & adxl357::kStatusDataReady)) return DeviceStatus::kNotReady;
  *out = adxl357::DecodeSample(b + (adxl357::kRegXData3 - adxl357::kRegStatus));
  ++fresh_count_;
  return DeviceStatus::kOk;
}

DeviceStatus Adxl357::ReadData(RawSample* out) {
  uint8_t d[adxl357::kDataBytes];
  const I2cStatus bus = bus_.Read(addr7_, adxl357::kRegXData3, d, sizeof d);
  const DeviceStatus st = adxl357::CheckData(bus, d, out);
  if (st == DeviceStatus::kOk) ++fresh_count_;
  return st;
}

}  // namespace drivers
}  // namespace ja
