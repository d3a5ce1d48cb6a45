#include "app/app_config.hpp"

#include "protocol/crc16.hpp"
#include "protocol/messages.hpp"
#include "protocol/wire.hpp"

namespace ja {
namespace app {

namespace {

constexpr int32_t kDefaultNearUm = 47500;  // 4.75 cm from the joint
constexpr int32_t kDefaultFarUm = 275000;  // 27.5 cm

bool ValidRange(uint8_t model, uint8_t range_g) {
  switch (static_cast<proto::SensorModel>(model)) {
    case proto::SensorModel::kAdxl345:
    case proto::SensorModel::kBno055:
      return range_g == 2 || range_g == 4 || range_g == 8 || range_g == 16;
    case proto::SensorModel::kAdxl357:
      return range_g == 10 || range_g == 20 || range_g == 40;
    default:
      return false;
  }
}

bool ValidCoordinate(int32_t v) { return v <= kMaxCoordinateUm && v >= -kMaxCoordinateUm; }

}  // namespace

void SetDefaults(Config& c, uint16_t rate_hz) {
  c.rate_hz = rate_hz;
  for (int l = 0; l < 2; ++l) {
    c.joint_um[l][0] = 0;
    c.joint_um[l][1] = 0;
  }
  c.sensor_count = 4;
  for (uint8_t i = 0; i < kMaxSensors; ++i) {
    SensorConfig& s = c.sensors[i];
    s.link = static_cast<uint8_t>(i < 2 ? proto::Link::kA : proto::Link::kB);
    s.model =
        static_cast<uint8_t>(i < 4 ? proto::SensorModel::kAdxl345 : proto::SensorModel::kNone);
    s.mux_channel = i;
    s.address = 0x53;
    s.range_g = 4;
    s.x_um = (i % 2 == 0) ? kDefaultNearUm : kDefaultFarUm;
    s.y_um = 0;
    s.rotation_urad = 0;
    Calibration& k = c.calibration[i];
    for (int j = 0; j < 9; ++j) k.s_q24[j] = (j % 4 == 0) ? kOneQ24 : 0;
    for (int j = 0; j < 3; ++j) k.o_umps2[j] = 0;
  }
  c.filter.kind = static_cast<uint8_t>(proto::FilterKind::kEkf);
  c.filter.accel_sigma_u = 0;
  c.filter.p0_q16 = 0;
  c.filter.flags = 0;
}

bool IsPlausibleCalibration(const int32_t s_q24[9], const int32_t o_umps2[3]) {
  for (int i = 0; i < 9; ++i) {
    if (s_q24[i] > kMaxCalibrationEntryQ24 || s_q24[i] < -kMaxCalibrationEntryQ24) return false;
  }
  for (int i = 0; i < 3; ++i) {
    if (o_umps2[i] > kMaxCalibrationOffsetU || o_umps2[i] < -kMaxCalibrationOffsetU) return false;
  }
  float m[9];
  for (int i = 0; i < 9; ++i) m[i] = static_cast<float>(s_q24[i]) / static_cast<float>(kOneQ24);
  // det S by the first row's cofactors.
  const float det = m[0] * (m[4] * m[8] - m[5] * m[7]) - m[1] * (m[3] * m[8] - m[5] * m[6]) +
                    m[2] * (m[3] * m[7] - m[4] * m[6]);
  return det >= kMinCalibrationDeterminant || det <= -kMinCalibrationDeterminant;
}

bool IsValidSensor(const SensorConfig& s) {
  return s.link <= 1 && ValidRange(s.model, s.range_g) && s.address < 0x80 &&
         (s.mux_channel < 8 || s.mux_channel == kNoMux) && ValidCoordinate(s.x_um) &&
         ValidCoordinate(s.y_um);
}

bool IsValid(const Config& c) {
  if (c.rate_hz < kMinRateHz || c.rate_hz > kMaxRateHz) return false;
  if (c.sensor_count > kMaxSensors) return false;
  for (uint8_t i = 0; i < c.sensor_count; ++i) {
    // A slot not set yet (model none) is allowed: it is reported as not configured.
    if (c.sensors[i].model == static_cast<uint8_t>(proto::SensorModel::kNone)) continue;
    if (!IsValidSensor(c.sensors[i])) return false;
  }
  for (int l = 0; l < 2; ++l) {
    if (!ValidCoordinate(c.joint_um[l][0]) || !ValidCoordinate(c.joint_um[l][1])) return false;
  }
  return c.filter.kind <= static_cast<uint8_t>(proto::FilterKind::kOff) && c.filter.flags == 0;
}

void SerialiseConfig(const Config& c, uint8_t* p) {
  proto::put_u16(p, c.rate_hz);
  p += 2;
  for (int l = 0; l < 2; ++l) {
    for (int k = 0; k < 2; ++k, p += 4) proto::put_i32(p, c.joint_um[l][k]);
  }
  *p++ = c.sensor_count;
  for (uint8_t i = 0; i < kMaxSensors; ++i) {
    const SensorConfig& s = c.sensors[i];
    p[0] = s.link;
    p[1] = s.model;
    p[2] = s.mux_channel;
    p[3] = s.address;
    p[4] = s.range_g;
    proto::put_i32(p + 5, s.x_um);
    proto::put_i32(p + 9, s.y_um);
    proto::put_i32(p + 13, s.rotation_urad);
    p += 17;
  }
  for (uint8_t i = 0; i < kMaxSensors; ++i) {
    for (int j = 0; j < 9; ++j, p += 4) proto::put_i32(p, c.calibration[i].s_q24[j]);
    for (int j = 0; j < 3; ++j, p += 4) proto::put_i32(p, c.calibration[i].o_umps2[j]);
  }
  p[0] = c.filter.kind;
  proto::put_u32(p + 1, c.filter.accel_sigma_u);
  proto::put_u32(p + 5, c.filter.p0_q16);
  p[9] = c.filter.flags;
}

void DeserialiseConfig(const uint8_t* p, Config& c) {
  c.rate_hz = proto::get_u16(p);
  p += 2;
  for (int l = 0; l < 2; ++l) {
    for (int k = 0; k < 2; ++k, p += 4) c.joint_um[l][k] = proto::get_i32(p);
  }
  c.sensor_count = *p++;
  for (uint8_t i = 0; i < kMaxSensors; ++i) {
    SensorConfig& s = c.sensors[i];
    s.link = p[0];
    s.model = p[1];
    s.mux_channel = p[2];
    s.address = p[3];
    s.range_g = p[4];
    s.x_um = proto::get_i32(p + 5);
    s.y_um = proto::get_i32(p + 9);
    s.rotation_urad = proto::get_i32(p + 13);
    p += 17;
  }
  for (uint8_t i = 0; i < kMaxSensors; ++i) {
    for (int j = 0; j < 9; ++j, p += 4) c.calibration[i].s_q24[j] = proto::get_i32(p);
    for (int j = 0; j < 3; ++j, p += 4) c.calibration[i].o_umps2[j] = proto::get_i32(p);
  }
  c.filter.kind = p[0];
  c.filter.accel_sigma_u = proto::get_u32(p + 1);
  c.filter.p0_q16 = proto::get_u32(p + 5);
  c.filter.flags = p[9];
}

uint8_t ReadStoredPayload(Eeprom& eeprom, uint16_t first, uint16_t count, uint8_t* out) {
  if (eeprom.Size() < kEepromBase + kEepromImageSize) {
    return static_cast<uint8_t>(proto::EepromState::kEmptyDefaults);
  }
  uint8_t header[kEepromHeaderSize];
  bool erased = true;
  for (uint16_t i = 0; i < kEepromHeaderSize; ++i) {
    header[i] = eeprom.Read(static_cast<uint16_t>(kEepromBase + i));
    erased = erased && header[i] == 0xFF;
  }
  if (erased) return static_cast<uint8_t>(proto::EepromState::kEmptyDefaults);
  const uint16_t magic = proto::get_u16(header);
  const uint8_t layout = header[2];
  const uint16_t length = proto::get_u16(header + 4);
  if (magic == kEepromMagic && layout > kEepromLayoutVersion) {
    return static_cast<uint8_t>(proto::EepromState::kNewerLayoutDefaults);
  }
  const uint8_t bad = static_cast<uint8_t>(proto::EepromState::kBadChecksumDefaults);
  if (magic != kEepromMagic || layout != kEepromLayoutVersion || length != kEepromPayloadSize) {
    return bad;
  }
  uint16_t crc = proto::crc16(header, kEepromHeaderSize);
  for (uint16_t i = 0; i < kEepromPayloadSize; ++i) {
    const uint8_t b = eeprom.Read(static_cast<uint16_t>(kEepromBase + kEepromHeaderSize + i));
    crc = proto::crc16_update(crc, b);
    if (i >= first && i < first + count) out[i - first] = b;
  }
  const uint16_t at = kEepromBase + kEepromHeaderSize + kEepromPayloadSize;
  const uint16_t stored = static_cast<uint16_t>(
      eeprom.Read(at) | (static_cast<uint16_t>(eeprom.Read(static_cast<uint16_t>(at + 1))) << 8));
  if (stored != crc) return bad;
  return static_cast<uint8_t>(proto::EepromState::kOk);
}

uint8_t LoadConfig(Eeprom& eeprom, Config& c, uint16_t factory_rate_hz) {
  SetDefaults(c, factory_rate_hz);
  uint8_t payload[kEepromPayloadSize];
  const uint8_t state = ReadStoredPayload(eeprom, 0, kEepromPayloadSize, payload);
  if (state != static_cast<uint8_t>(proto::EepromState::kOk)) return state;
  DeserialiseConfig(payload, c);
  if (!IsValid(c)) {
    SetDefaults(c, factory_rate_hz);
    return static_cast<uint8_t>(proto::EepromState::kBadChecksumDefaults);
  }
  return static_cast<uint8_t>(proto::EepromState::kOk);
}

bool SaveConfig(Eeprom& eeprom, const Config& c) {
  if (eeprom.Size() < kEepromBase + kEepromImageSize) return false;
  uint8_t image[kEepromImageSize];
  proto::put_u16(image, kEepromMagic);
  image[2] = kEepromLayoutVersion;
  image[3] = 0;
  proto::put_u16(image + 4, kEepromPayloadSize);
  SerialiseConfig(c, image + kEepromHeaderSize);
  proto::put_u16(image + kEepromHeaderSize + kEepromPayloadSize,
                 proto::crc16(image, kEepromHeaderSize + kEepromPayloadSize));
  for (uint16_t i = 0; i < kEepromImageSize; ++i) {
    eeprom.Write(static_cast<uint16_t>(kEepromBase + i), image[i]);
  }
  if (!eeprom.Commit()) return false;
  for (uint16_t i = 0; i < kEepromImageSize; ++i) {
    if (eeprom.Read(static_cast<uint16_t>(kEepromBase + i)) != image[i]) return false;
  }
  return true;
}

void EraseConfig(Eeprom& eeprom) {
  if (eeprom.Size() < kEepromBase + kEepromHeaderSize) return;
  for (uint16_t i = 0; i < kEepromHeaderSize; ++i) {
    eeprom.Write(static_cast<uint16_t>(kEepromBase + i), 0xFF);
  }
  eeprom.Commit();
}

}  // namespace app
}  // namespace ja
