#include "drivers/adxl345.hpp"

namespace ja {
namespace drivers {

DeviceStatus Adxl345::Configure(const adxl345::Settings& s) {
  using namespace adxl345;
  uint8_t id = 0;
  I2cStatus st = ReadRegister(bus_, addr7_, kRegDevId, &id);
  if (st != I2cStatus::kOk) return DeviceStatus::kBusFault;
  if (id != kDevId) return DeviceStatus::kWrongId;
  const uint8_t steps[][2] = {
      {kRegPowerCtl, kPowerStandby},
      {kRegDataFormat, static_cast<uint8_t>(kFullRes | static_cast<uint8_t>(s.range))},
      {kRegBwRate, static_cast<uint8_t>(s.rate)},
      {kRegIntMap, 0x00},  // every interrupt on INT1
      {kRegIntEnable, kIntDataReady},
      {kRegFifoCtl, kFifoBypass},
      {kRegPowerCtl, kPowerMeasure},
  };
  for (const auto& step : steps) {
    st = WriteRegister(bus_, addr7_, step[0], step[1]);
    if (st != I2cStatus::kOk) return DeviceStatus::kBusFault;
  }
  // Read back the data format: catches a part that ACKs but ignores writes.
  uint8_t format = 0;
  st = ReadRegister(bus_, addr7_, kRegDataFormat, &format);
  if (st != I2cStatus::kOk) return DeviceStatus::kBusFault;
  if (format != static_cast<uint8_t>(kFullRes | static_cast<uint8_t>(s.range))) {
    return DeviceStatus::kVerifyFailed;
  }
  return DeviceStatus::kOk;
}

DeviceStatus Adxl345::ReadSample(RawSample* out) {
  uint8_t b[8];
  const I2cStatus bus = bus_.Read(addr7_, adxl345::kRegIntSource, b, sizeof b);
  const DeviceStatus st = adxl345::CheckSample(bus, b, out);
  if (st == DeviceStatus::kOk) ++fresh_count_;
  return st;
}

DeviceStatus Adxl345::ReadData(RawSample* out) {
  uint8_t d[adxl345::kDataBytes];
  const I2cStatus bus = bus_.Read(addr7_, adxl345::kRegDataX0, d, sizeof d);
  const DeviceStatus st = adxl345::CheckData(bus, d, out);
  if (st == DeviceStatus::kOk) ++fresh_count_;
  return st;
}

}  // namespace drivers
}  // namespace ja
