// ADXL357 3-axis accelerometer (ADXL355 register map; docs/sensors.md §A2) over an I2cBus:
// identification, standby -> range and output data rate -> measurement, 20-bit samples.
#pragma once

#include <stdint.h>

#include "drivers/conversion.hpp"
#include "drivers/i2c_bus.hpp"

namespace ja {
namespace drivers {
namespace adxl357 {
constexpr uint8_t kAddressAselLow = 0x1D;
constexpr uint8_t kAddressAselHigh = 0x53;
constexpr uint8_t kRegDevIdAd = 0x00;   // 0xAD
constexpr uint8_t kRegDevIdMst = 0x01;  // 0x1D
constexpr uint8_t kRegPartId = 0x02;    // 0xED
constexpr uint8_t kDevIdAd = 0xAD;
constexpr uint8_t kDevIdMst = 0x1D;
constexpr uint8_t kPartId = 0xED;
constexpr uint8_t kRegStatus = 0x04;    // bit0 DATA_RDY
constexpr uint8_t kRegXData3 = 0x08;    // X3 X2 X1 Y3 Y2 Y1 Z3 Z2 Z1, big-endian, left-justified
constexpr uint8_t kDataBytes = 9;       // ReadData's burst from XDATA3
constexpr uint8_t kRegFilter = 0x28;    // [3:0] ODR_LPF, [6:4] HPF corner
constexpr uint8_t kRegRange = 0x2C;     // [1:0] range, bit6 INT_POL, bit7 I2C_HS
constexpr uint8_t kRegPowerCtl = 0x2D;  // bit0 STANDBY, bit1 TEMP_OFF, bit2 DRDY_OFF
constexpr uint8_t kStatusDataReady = 0x01;
constexpr uint8_t kPowerStandby = 0x01;
constexpr uint8_t kPowerMeasure = 0x00;
constexpr uint8_t kRangeMask = 0x03;
constexpr uint8_t kOdrMask = 0x0F;

/// Range codes and nominal sensitivity: 51200 / 25600 / 12800 LSB/g (19.5/39/78 ug/LSB).
enum class Range : uint8_t { k10g = 1, k20g = 2, k40g = 3 };
/// ODR_LPF codes: ODR = 4000 Hz / 2^code (LPF corner ~ ODR/4). No 100/400 Hz code exists.
enum class Odr : uint8_t {
  k4000Hz = 0,
  k2000Hz = 1,
  k1000Hz = 2,
  k500Hz = 3,
  k250Hz = 4,
  k125Hz = 5,
  k62_5Hz = 6,
};
constexpr float OdrHz(Odr o) { return 4000.0f / static_cast<float>(1u << static_cast<uint8_t>(o)); }
constexpr float GPerCount(Range r) {
  return 1.0f / (51200.0f / static_cast<float>(1u << (static_cast<uint8_t>(r) - 1u)));
}

struct Settings {
  Range range = Range::k10g;
  Odr odr = Odr::k1000Hz;  // fresh data in every 500 Hz frame
};
constexpr Settings kDefaultSettings{};

/// One axis from its three bytes: x = (D3 << 12) | (D2 << 4) | (D1 >> 4), 20-bit two's complement.
inline int32_t DecodeAxis(const uint8_t* d) {
  const uint32_t v = (static_cast<uint32_t>(d[0]) << 12) | (static_cast<uint32_t>(d[1]) << 4) |
                     (static_cast<uint32_t>(d[2]) >> 4);
  return SignExtend(v, 20);
}

/// Decodes the 9 data bytes XDATA3..ZDATA1.
inline RawSample DecodeSample(const uint8_t* d) {
  RawSample s;
  s.x = DecodeAxis(d);
  s.y = DecodeAxis(d + 3);
  s.z = DecodeAxis(d + 6);
  return s;
}

/// Judges one read of the nine data registers XDATA3..ZDATA1 (0x08..0x10, bus status `bus`): a
/// failed read is kBusFault, else *out = the decoded counts and kOk. No DATA_RDY check: for a
/// reader whose schedule guarantees a new conversion between two reads (an output data rate of
/// at least 1.6 x the read rate), which then reads four bytes less (STATUS..TEMP1).
inline DeviceStatus CheckData(I2cStatus bus, const uint8_t* d, RawSample* out) {
  if (bus != I2cStatus::kOk) return DeviceStatus::kBusFault;
  *out = DecodeSample(d);
  return DeviceStatus::kOk;
}
}  // namespace adxl357

class Adxl357 {
 public:
  Adxl357(I2cBus& bus, uint8_t addr7) : bus_(bus), addr7_(addr7) {}

  /// Checks the three ID registers, enters standby, sets range (keeping INT_POL/I2C_HS) and
  /// ODR (keeping the high-pass setting), verifies them, then starts measuring.
  DeviceStatus Configure(const adxl357::Settings& s = adxl357::kDefaultSettings);
  /// Reads STATUS..ZDATA1 (0x04..0x10, 13 bytes) in one transaction; kNotReady if DATA_RDY
  /// was clear.
  DeviceStatus ReadSample(RawSample* out);
  /// Reads XDATA3..ZDATA1 alone (9 bytes, adxl357::CheckData): for a caller whose output data
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
