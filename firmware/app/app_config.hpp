// The application's configuration and calibration (what set_* commands change and save_eeprom
// persists), its defaults, and its EEPROM image: a header with a magic, a layout version and the
// payload length, the payload in explicit little-endian bytes (identical on AVR and x86), and a
// CRC-16/CCITT-FALSE over both. Units are the protocol's (µm, µrad, Q24, µm/s^2), so a command's
// fields are stored as received and the EEPROM image needs no floating point.
#pragma once

#include <stddef.h>
#include <stdint.h>

#include "app/hal.hpp"

namespace ja {
namespace app {

constexpr uint8_t kMaxSensors = 8;  // sensor slots (the protocol allows 16; 8 saves RAM)
constexpr uint8_t kNoMux = 255;     // mux_channel of a sensor wired to the bus directly
constexpr uint16_t kMinRateHz = 10;
constexpr uint16_t kMaxRateHz = 1000;
// The factory rate where the board gives none (Hal::factory_rate_hz): the native board.
constexpr uint16_t kFactoryRateHz = 500;
constexpr int32_t kMaxCoordinateUm = 10000000;  // |x|, |y| <= 10 m
constexpr int32_t kOneQ24 = 16777216;
// Command bounds (protocol/messages.toml says the same): a calibration a = S v + o must have
// |det S| >= 1/64, |S_ij| <= 4 and |o_i| <= 50 m/s^2; a fixed noise sigma 100e-6..10 m/s^2.
constexpr int32_t kMaxCalibrationEntryQ24 = 4 * kOneQ24;
constexpr int32_t kMaxCalibrationOffsetU = 50000000;        // um/s^2
constexpr float kMinCalibrationDeterminant = 1.0f / 64.0f;  // each axis gain >= ~1/4
constexpr uint32_t kMinAccelSigmaU = 100;                   // um/s^2
constexpr uint32_t kMaxAccelSigmaU = 10000000;              // um/s^2

/// One sensor slot (rig order: links a then b).
struct SensorConfig {
  uint8_t link;           // proto::Link
  uint8_t model;          // proto::SensorModel (kNone = empty slot)
  uint8_t mux_channel;    // 0..7, or kNoMux
  uint8_t address;        // 7-bit I2C address
  uint8_t range_g;        // g: adxl345/bno055 2, 4, 8, 16; adxl357 10, 20, 40
  int32_t x_um, y_um;     // position in the link frame, µm
  int32_t rotation_urad;  // sensor frame about z relative to the link, µrad
};

/// a = S v + o in the sensor frame (v: counts scaled to m/s^2). Identity and zero by default.
struct Calibration {
  int32_t s_q24[9];    // row-major, Q24
  int32_t o_umps2[3];  // µm/s^2
};

struct FilterConfig {
  uint8_t kind;            // proto::FilterKind
  uint32_t accel_sigma_u;  // µm/s^2 per reading; 0 = datasheet density and LSB (APP.md)
  uint32_t p0_q16;         // 0 or 1.0 (65536): the filter's own initial covariance
  uint8_t flags;           // reserved, 0
};

struct Config {
  uint16_t rate_hz;        // loop and frame rate, Hz
  int32_t joint_um[2][2];  // hinge O in link a's and link b's frame, µm
  uint8_t sensor_count;    // slots in use, <= kMaxSensors
  SensorConfig sensors[kMaxSensors];
  Calibration calibration[kMaxSensors];
  FilterConfig filter;
};

/// Factory defaults: four ADXL345 (±4 g) at 0x53 behind a TCA9548A at 0x70, channels 0-3; links a
/// and b each 30 cm with sensors at 4.75 and 27.5 cm from the joint (the paper's rig); 500 Hz.
void SetDefaults(Config& c, uint16_t rate_hz = kFactoryRateHz);

/// Checks every field against what the app can run (range codes, addresses, counts). A config
/// read from EEPROM that fails this is treated like a bad checksum.
bool IsValid(const Config& c);
bool IsValidSensor(const SensorConfig& s);
/// A calibration S (row-major, Q24) and offset o (um/s^2) within the command bounds above.
bool IsPlausibleCalibration(const int32_t s_q24[9], const int32_t o_umps2[3]);

// ---- EEPROM image ----
constexpr uint16_t kEepromMagic = 0x414A;  // "JA" little-endian
constexpr uint8_t kEepromLayoutVersion = 1;
constexpr uint16_t kEepromHeaderSize = 6;  // magic u16, layout u8, reserved u8, length u16
constexpr uint16_t kEepromPayloadSize =
    2 + 16 + 1 + kMaxSensors * 17 + kMaxSensors * 48 + 10;  // see SerialiseConfig
constexpr uint16_t kEepromImageSize = kEepromHeaderSize + kEepromPayloadSize + 2;
constexpr uint16_t kEepromBase = 0;  // address of the image

/// Writes the payload (kEepromPayloadSize bytes).
void SerialiseConfig(const Config& c, uint8_t* out);
/// Reads a payload written by SerialiseConfig.
void DeserialiseConfig(const uint8_t* in, Config& c);

/// Reads the stored image: checks its header and the CRC over the whole payload, and copies the
/// payload bytes [first, first + count) to `out` (no copy of the rest). The result is a
/// proto::EepromState: ok, empty (store too small or header erased), newer layout, bad checksum
/// (another magic, layout or length, or a CRC failure); `out` is meaningful only when ok.
uint8_t ReadStoredPayload(Eeprom& eeprom, uint16_t first, uint16_t count, uint8_t* out);
/// Loads the configuration; on any problem `c` holds the defaults and the result says why
/// (proto::EepromState: ok, empty, bad checksum, newer layout).
uint8_t LoadConfig(Eeprom& eeprom, Config& c, uint16_t factory_rate_hz = kFactoryRateHz);
/// Writes the image, commits it (Eeprom::Commit) and reads it back; false if the store is too
/// small, the commit fails or the read-back differs.
bool SaveConfig(Eeprom& eeprom, const Config& c);
/// Erases the image's header and commits it (the next boot finds an empty EEPROM: factory
/// defaults).
void EraseConfig(Eeprom& eeprom);

}  // namespace app
}  // namespace ja
