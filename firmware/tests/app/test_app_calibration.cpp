// The application on x86 over in-test fakes, calibration in fixed point (APP.md "Calibration in
// fixed point"): the counts-to-link-frame map against the float formula, a static pose recovered
// through a mounting rotation and a calibration, an unusable calibration refused, get_calibration.
#include <math.h>

#include "app_test_helpers.hpp"
#include "check.hpp"

namespace {

namespace proto = ja::proto;
namespace ss = proto::sensor_status;
namespace fh = proto::filter_health;
using ja::app::App;
using ja_test::kAdxl345;
using ja_test::kAdxl357;
using ja_test::kBno055;
using ja_test::kG;
using ja_test::kPi;
using ja_test::MakeBoard;
using ja_test::SetStaticPose;
using ja_test::Stream;
using ja_test::ThetaDeg;

void TestMountingRotationAndCalibration() {
  auto b = MakeBoard();
  const double theta = 0.7;
  SetStaticPose(*b, theta);
  // Sensor 2 is mounted at 90 deg: it reads R(90)^T of its link-frame force.
  float* f = b->bus.chips[2].force_mps2;
  const float x = f[0], y = f[1];
  f[0] = y;
  f[1] = -x;
  // Sensor 3 has a gain of 2 on every axis and an offset of +1 m/s^2 on x: S = I/2, o = -0.5.
  for (int k = 0; k < 3; ++k) b->bus.chips[3].force_mps2[k] *= 2.0f;
  b->bus.chips[3].force_mps2[0] += 1.0f;
  App app(b->hal);
  app.Begin();
  proto::SetSensor s = {};
  s.slot = 2;
  s.count = 4;
  s.link = 1;
  s.model = kAdxl345;
  s.mux_channel = 2;
  s.address = 0x53;
  s.range_g = 4;
  s.x = 47500;
  s.rotation = 1570796;
  const uint16_t q1 = b->Command(s);
  proto::SetCalibration c = {};
  c.slot = 3;
  c.s00 = c.s11 = c.s22 = 1 << 23;
  c.ox = -500000;
  const uint16_t q2 = b->Command(c);
  b->Run(app, 50000);
  CHECK_EQ(b->AckError(proto::SetSensor::kId, q1), 0);
  CHECK_EQ(b->AckError(proto::SetCalibration::kId, q2), 0);
  // Gain 2 at +-4 g would saturate near 2 g: use +-8 g for that sensor.
  s.slot = 3;
  s.mux_channel = 3;
  s.x = 275000;
  s.rotation = 0;
  s.range_g = 8;
  b->Command(s);
  b->Run(app, 50000);
  b->ClearFrames();
  b->Command(Stream(proto::stream_mode::kSampleEstimate));
  b->Run(app, 1000000);
  proto::SampleEstimate m;
  CHECK(b->Last(&m));
  CHECK(m.health & fh::kRunning);
  for (int i = 0; i < 4; ++i) CHECK_EQ(m.sensors[i].status, 0);
  CHECK_NEAR(ThetaDeg(m), theta * 180.0 / kPi, 1.0);
  // The calibrated link-frame readings of link b's sensors: R(theta)^T f_a within a few LSB.
  for (int i = 2; i < 4; ++i) {
    const ja::app::LinkReading r = app.sensor(i).reading();
    CHECK_NEAR(r.x_q16 / 65536.0, cos(theta) * 0.6 * kG - sin(theta) * 0.8 * kG, 0.12);
    CHECK_NEAR(r.y_q16 / 65536.0, sin(theta) * 0.6 * kG + cos(theta) * 0.8 * kG, 0.12);
  }
}

void TestCalibrationMap() {
  ja::app::SensorConfig s = {};
  s.model = kAdxl357;
  s.range_g = 20;
  s.rotation_urad = 523599;  // 30 deg
  ja::app::Calibration k = {};
  const double S[9] = {1.01, 0.02, -0.01, 0.005, 0.98, 0.03, 0.0, 0.0, 1.0};
  for (int j = 0; j < 9; ++j) k.s_q24[j] = static_cast<int32_t>(lround(S[j] * 16777216.0));
  k.o_umps2[0] = 120000;
  k.o_umps2[1] = -340000;
  k.o_umps2[2] = 50000;
  const ja::app::CalibrationMap map = ja::app::MakeCalibrationMap(s, k);
  CHECK(!map.saturated);
  const double scale = 9.80665 / 25600.0;
  const int32_t counts[3][3] = {{12345, -23456, 25600}, {-400000, 300000, 5}, {0, 0, 0}};
  for (const auto& c : counts) {
    double v[3], a[3];
    for (int j = 0; j < 3; ++j) v[j] = c[j] * scale;
    for (int r = 0; r < 3; ++r) {
      a[r] = k.o_umps2[r] * 1e-6;
      for (int j = 0; j < 3; ++j) a[r] += S[3 * r + j] * v[j];
    }
    const double rot = 0.523599;
    const double lx = cos(rot) * a[0] - sin(rot) * a[1], ly = sin(rot) * a[0] + cos(rot) * a[1];
    uint16_t sat = 0;
    ja::drivers::RawSample raw;
    raw.x = c[0];
    raw.y = c[1];
    raw.z = c[2];
    const ja::app::LinkReading r = ja::app::ApplyCalibration(map, raw, &sat);
    CHECK_EQ(sat, 0);
    CHECK_NEAR(r.x_q16 / 65536.0, lx, 1e-3);
    CHECK_NEAR(r.y_q16 / 65536.0, ly, 1e-3);
  }
  // A reading beyond Q15.16 saturates and is counted.
  k.s_q24[0] = 0x7FFFFFFF;
  s.model = kAdxl345;
  s.range_g = 16;
  const ja::app::CalibrationMap big = ja::app::MakeCalibrationMap(s, k);
  ja::drivers::RawSample raw;
  raw.x = 4095;
  raw.y = raw.z = 0;
  uint16_t sat = 0;
  ja::app::ApplyCalibration(big, raw, &sat);
  CHECK_EQ(sat, 0);  // 127.99 * 0.038 * 4095 ~ 20 000 m/s^2 still fits Q15.16
  // The rail or one LSB short of it (at 1600/3200 Hz ODR the positive rail reads 510 at 2 g).
  CHECK_EQ(ja::app::SaturationCounts(kAdxl345, 2), 510);
  CHECK_EQ(ja::app::SaturationCounts(kAdxl345, 16), 4094);
  CHECK_EQ(ja::app::SaturationCounts(kBno055, 4), 3921);
}

void TestGetCalibration() {
  auto b = MakeBoard();
  App app(b->hal);
  app.Begin();
  proto::GetCalibration get;
  get.slot = 1;
  get.source = static_cast<uint8_t>(proto::CalibrationSource::kEeprom);
  uint16_t q = b->Command(get);  // nothing stored yet
  b->Run(app, 20000);
  CHECK_EQ(b->AckError(proto::GetCalibration::kId, q),
           static_cast<uint8_t>(proto::ErrorCode::kEepromFailed));
  proto::SetCalibration c = {};
  c.slot = 1;
  c.s00 = 17000000;
  c.s11 = 1 << 24;
  c.s12 = -4242;
  c.s22 = 16000000;
  c.oz = -98000;
  b->Command(c);
  proto::SaveEeprom save;
  save.confirm = ja::app::kSaveConfirm;
  b->Command(save);
  c.s00 = 17000001;  // changed after the save: running and stored now differ
  b->Command(c);
  b->Run(app, 100000);
  b->ClearFrames();
  q = b->Command(get);
  get.source = static_cast<uint8_t>(proto::CalibrationSource::kRunning);
  const uint16_t q2 = b->Command(get);
  b->Run(app, 20000);
  CHECK_EQ(b->AckError(proto::GetCalibration::kId, q), 0);
  CHECK_EQ(b->AckError(proto::GetCalibration::kId, q2), 0);
  proto::Calibration stored, running;
  CHECK(b->Find(&stored, 0) && b->Find(&running, 1));
  CHECK_EQ(stored.source, static_cast<uint8_t>(proto::CalibrationSource::kEeprom));
  CHECK_EQ(stored.slot, 1);
  CHECK_EQ(stored.s00, 17000000);
  CHECK_EQ(stored.s12, -4242);
  CHECK_EQ(stored.s22, 16000000);
  CHECK_EQ(stored.oz, -98000);
  CHECK_EQ(running.source, static_cast<uint8_t>(proto::CalibrationSource::kRunning));
  CHECK_EQ(running.s00, 17000001);
  CHECK_EQ(running.s12, -4242);
  // A damaged image (one payload byte) is refused, a slot past the count is a bad value.
  b->eeprom.bytes[ja::app::kEepromBase + ja::app::kEepromHeaderSize + 3] ^= 0x01;
  get.source = static_cast<uint8_t>(proto::CalibrationSource::kEeprom);
  q = b->Command(get);
  get.slot = 4;
  const uint16_t q3 = b->Command(get);
  b->Run(app, 20000);
  CHECK_EQ(b->AckError(proto::GetCalibration::kId, q),
           static_cast<uint8_t>(proto::ErrorCode::kEepromFailed));
  CHECK_EQ(b->AckError(proto::GetCalibration::kId, q3),
           static_cast<uint8_t>(proto::ErrorCode::kBadValue));
}

/// A calibration the fixed-point map could not hold (S = 100: |M| >= 2) is refused by
/// set_calibration (bad_calibration) and changes nothing: the sensor keeps its calibration, no
/// flag, the filter runs. (The bad_calibration status bit stays for what the bounds cannot see.)
void TestUnusableCalibrationIsFlagged() {
  auto b = MakeBoard();
  SetStaticPose(*b, 0.3);
  App app(b->hal);
  app.Begin();
  proto::SetCalibration c = {};
  c.slot = 1;
  c.s00 = 100 << 24;
  c.s11 = c.s22 = 1 << 24;
  const uint16_t refused = b->Command(c);
  b->Command(Stream(proto::stream_mode::kSampleEstimate | proto::stream_mode::kStatus, 100));
  b->Run(app, 300000);
  CHECK_EQ(b->AckError(proto::SetCalibration::kId, refused),
           static_cast<uint8_t>(proto::ErrorCode::kBadCalibration));
  proto::SampleEstimate m;
  CHECK(b->Last(&m));
  CHECK_EQ(m.sensors[1].status & ss::kBadCalibration, 0);
  CHECK(m.health & fh::kRunning);
}

}  // namespace

int main() {
  TestMountingRotationAndCalibration();
  TestCalibrationMap();
  TestGetCalibration();
  TestUnusableCalibrationIsFlagged();
  return ja_test::Finish("test_app_calibration");
}
