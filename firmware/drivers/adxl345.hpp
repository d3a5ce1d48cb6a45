// ADXL345 3-axis accelerometer (docs/sensors.md §A1), full-resolution mode, over an I2cBus.
#pragma once

#include <stdint.h>

#include "drivers/conversion.hpp"
#include "drivers/i2c_bus.hpp"

namespace ja {
namespace drivers {
namespace adxl345 {
constexpr uint8_t kAddressAltLow = 0x53;
constexpr uint8_t kAddressAltHigh = 0x1D;
constexpr uint8_t kRegDevId = 0x00;
constexpr uint8_t kDevId = 0xE5;
constexpr uint8_t kRegBwRate = 0x2C;    // [3:0] rate code, bit4 LOW_POWER
constexpr uint8_t kRegPowerCtl = 0x2D;  // bit3 MEASURE
constexpr uint8_t kRegIntEnable = 0x2E;
constexpr uint8_t kRegIntMap = 0x2F;
constexpr uint8_t kRegIntSource = 0x30;   // bit7 DATA_READY
constexpr uint8_t kRegDataFormat = 0x31;  // [1:0] range, bit3 FULL_RES
constexpr uint8_t kRegDataX0 = 0x32;      // X0 X1 Y0 Y1 Z0 Z1, little-endian
constexpr uint8_t kDataBytes = 6;         // ReadData's burst from DATAX0
constexpr uint8_t kRegFifoCtl = 0x38;
constexpr uint8_t kPowerMeasure = 0x08;
constexpr uint8_t kPowerStandby = 0x00;
constexpr uint8_t kFullRes = 0x08;
constexpr uint8_t kIntDataReady = 0x80;
constexpr uint8_t kFifoBypass = 0x00;
/// Full resolution: 3.9 mg/LSB at every range (256 LSB/g at +-2 g).
constexpr float kGPerCountFullRes = 0.0039f;
constexpr float kMps2PerCount = kGPerCountFullRes * kStandardGravity;

enum class Range : uint8_t { k2g = 0, k4g = 1, k8g = 2, k16g = 3 };
/// Output data rate codes: ODR = 3200 Hz / 2^(15 - code); bandwidth = ODR / 2.
enum class Rate : uint8_t {
  k100Hz = 0x0A,
  k200Hz = 0x0B,
  k400Hz = 0x0C,
  k800Hz = 0x0D,
  k1600Hz = 0x0E,
  k3200Hz = 0x0F,
};
/// ODR in Hz of a rate code.
constexpr float RateHz(Rate r) {
  return 3200.0f / static_cast<float>(1u << (15u - static_cast<uint8_t>(r)));
}

struct Settings {
  Range range = Range::k2g;
  Rate rate = Rate::k800Hz;  // 800 Hz: every 500 Hz frame holds a fresh sample
};
constexpr Settings kDefaultSettings{};

/// Decodes the 6 bytes DATAX0..DATAZ1 (0x32..0x37): little-endian int16 counts.
inline RawSample DecodeData(const uint8_t* d) {
  RawSample s;
  s.x = static_cast<int16_t>(static_cast<uint16_t>(d[0] | (static_cast<uint16_t>(d[1]) << 8)));
  s.y = static_cast<int16_t>(static_cast<uint16_t>(d[2] | (static_cast<uint16_t>(d[3]) << 8)));
  s.z = static_cast<int16_t>(static_cast<uint16_t>(d[4] | (static_cast<uint16_t>(d[5]) << 8)));
  return s;
}

/// Decodes the 8 bytes INT_SOURCE..DATAZ1 (0x30..0x37): the data registers from b[2] on.
inline RawSample DecodeSample(const uint8_t* b) { return DecodeData(b + 2); }

/// Judges one read of the six data registers DATAX0..DATAZ1 (0x32..0x37, bus status `bus`):
/// a failed read is kBusFault, else *out = the decoded counts and kOk. No DATA_READY check: for
/// a reader whose schedule guarantees a new conversion between two reads (an output data rate
/// of at least 1.6 x the read rate), which then costs two bytes less a read on the bus.
inline DeviceStatus CheckData(I2cStatus bus, const uint8_t* b, RawSample* out) {
  if (bus != I2cStatus::kOk) return DeviceStatus::kBusFault;
  *out = DecodeData(b);
  return DeviceStatus::kOk;
}

/// Judges one sample read of INT_SOURCE..DATAZ1 (8 bytes b, read with bus status `bus`): a failed
/// read is kBusFault, DATA_READY clear is kNotReady (*out untouched), else *out = the decoded
/// counts and kOk. Adxl345::ReadSample and the app's batch fast path (sensor.cpp) both use it.
inline DeviceStatus CheckSample(I2cStatus bus, const uint8_t* b, RawSample* out) {
  if (bus != I2cStatus::kOk) return DeviceStatus::kBusFault;
  if (!(b[0] & kIntDataReady)) return DeviceStatus::kNotReady;
  *out = DecodeSample(b);
  return DeviceStatus::kOk;
}
}  // namespace adxl345

class Adxl345 {
 public:
  Adxl345(I2cBus& bus, uint8_t addr7) : bus_(bus), addr7_(addr7) {}

  /// Checks DEVID, then standby -> data format (full-res, range) -> rate -> data-ready
  /// interrupt on INT1 -> FIFO bypass -> measure.
  DeviceStatus Configure(const adxl345::Settings& s = adxl345::kDefaultSettings);
  /// Reads INT_SOURCE and the data registers in one 8-byte transaction. kNotReady (sample
  /// untouched) if DATA_READY was clear; on success the fresh-sample counter advances.
  DeviceStatus ReadSample(RawSample* out);
  /// Reads DATAX0..DATAZ1 alone (6 bytes, adxl345::CheckData): for a caller whose output data
  /// rate is at least 1.6 x its read rate, so that every read holds a new conversion.
  DeviceStatus ReadData(RawSample* out);
  uint16_t fresh_count() const { return fresh_count_; }

 private:
  I2cBus& bus_;
  uint8_t addr7_;
  uint16_t fresh_count_ = 0;
};

}  // namespace drivers
}  // namespace ja
