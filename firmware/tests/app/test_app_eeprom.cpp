// The application on x86 over in-test fakes, the EEPROM image (APP.md "EEPROM image"): the
// configuration saved and read back across a virtual reset, reboot and factory reset; a bad CRC,
// a newer layout and writes that do not stick; slots below the count not set yet; a store that
// keeps writes until Eeprom::Commit (the Pico's flash sector).
#include <string.h>

#include "app_test_helpers.hpp"
#include "check.hpp"

namespace {

namespace proto = ja::proto;
namespace ss = proto::sensor_status;
namespace fh = proto::filter_health;
using ja::app::App;
using ja_test::kAdxl345;
using ja_test::MakeBoard;
using ja_test::Stream;

void TestSlotsNotSetYet() {
  // count grows before every slot is set: the unset slot is reported, and the configuration
  // (with it) still saves and loads.
  auto b = MakeBoard();
  App app(b->hal);
  app.Begin();
  proto::SetSensor s = {};
  s.slot = 4;
  s.count = 6;
  s.link = 1;
  s.model = kAdxl345;
  s.mux_channel = 4;
  s.address = 0x53;
  s.range_g = 4;
  s.x = 100000;
  b->bus.Add(kAdxl345, 0x53, 4);
  const uint16_t q = b->Command(s);
  proto::SaveEeprom save;
  save.confirm = ja::app::kSaveConfirm;
  const uint16_t qs = b->Command(save);
  b->Command(Stream(proto::stream_mode::kSampleEstimate));
  b->Run(app, 20000);
  CHECK_EQ(b->AckError(proto::SetSensor::kId, q), 0);
  CHECK_EQ(b->AckError(proto::SaveEeprom::kId, qs), 0);
  proto::SampleEstimate m;
  CHECK(b->Last(&m));
  CHECK_EQ(m.sensors_count, 6);
  CHECK_EQ(m.sensors[4].status, 0);
  CHECK(m.sensors[5].status & ss::kNotConfigured);
  CHECK(m.health & fh::kRunning);
  App again(b->hal);
  again.Begin();
  CHECK_EQ(again.eeprom_state(), static_cast<uint8_t>(proto::EepromState::kOk));
  CHECK_EQ(again.config().sensor_count, 6);
}

void TestEepromRoundTrip() {
  auto b = MakeBoard();
  {
    App app(b->hal);
    app.Begin();
    proto::SetRate r = {};
    r.rate_hz = 250;
    b->Command(r);
    proto::SetJoint j = {};
    j.link = 0;
    j.x = 310000;
    j.y = -2000;
    b->Command(j);
    proto::SetCalibration c = {};
    c.slot = 2;
    c.s00 = 17000000;
    c.s11 = 16500000;
    c.s22 = 16777216;
    c.s01 = -12345;
    c.oy = 250000;
    b->Command(c);
    proto::SetFilter f = {};
    f.kind = static_cast<uint8_t>(proto::FilterKind::kAnalytical);
    f.accel_sigma = 40000;
    b->Command(f);
    proto::SaveEeprom save;
    save.confirm = ja::app::kSaveConfirm;
    const uint16_t q = b->Command(save);
    b->Run(app, 100000);
    CHECK_EQ(b->AckError(proto::SaveEeprom::kId, q), 0);
    CHECK_EQ(app.eeprom_state(), static_cast<uint8_t>(proto::EepromState::kOk));
  }
  // Virtual reset: a new App over the same EEPROM.
  b->ClearFrames();
  App app(b->hal);
  app.Begin();
  b->Flush();
  proto::Hello h;
  CHECK(b->Find(&h));
  CHECK_EQ(h.eeprom, static_cast<uint8_t>(proto::EepromState::kOk));
  CHECK_EQ(h.sample_rate_hz, 250);
  const ja::app::Config& c = app.config();
  CHECK_EQ(c.joint_um[0][0], 310000);
  CHECK_EQ(c.joint_um[0][1], -2000);
  CHECK_EQ(c.calibration[2].s_q24[0], 17000000);
  CHECK_EQ(c.calibration[2].s_q24[1], -12345);
  CHECK_EQ(c.calibration[2].o_umps2[1], 250000);
  CHECK_EQ(c.filter.kind, static_cast<uint8_t>(proto::FilterKind::kAnalytical));
  CHECK_EQ(c.filter.accel_sigma_u, 40000u);
  // The serialised image is the same both ways.
  uint8_t a[ja::app::kEepromPayloadSize], a2[ja::app::kEepromPayloadSize];
  ja::app::SerialiseConfig(c, a);
  ja::app::Config back;
  ja::app::DeserialiseConfig(a, back);
  ja::app::SerialiseConfig(back, a2);
  CHECK(memcmp(a, a2, sizeof a) == 0);

  // reset (reboot): ack, then the board restarts; a new hello with seq 0.
  b->ClearFrames();
  proto::Reset reset;
  reset.kind = static_cast<uint8_t>(proto::ResetKind::kReboot);
  const uint16_t q = b->Command(reset);
  b->Run(app, 50000);
  CHECK_EQ(b->system.reboots, 1);
  CHECK_EQ(b->AckError(proto::Reset::kId, q), 0);
  CHECK_EQ(b->Count<proto::Hello>(), 1);
  int hello_at = -1;
  for (int i = 0; i < b->frame_count; ++i) {
    if (b->frames[i].header.msg_id == proto::Hello::kId) hello_at = i;
  }
  CHECK(hello_at > 0 && b->frames[hello_at].header.seq == 0);
  CHECK_EQ(app.config().rate_hz, 250);

  // reset (factory defaults): the EEPROM is erased; the next boot runs on defaults.
  reset.kind = static_cast<uint8_t>(proto::ResetKind::kFactoryDefaults);
  b->Command(reset);
  b->Run(app, 50000);
  CHECK_EQ(b->system.reboots, 2);
  CHECK_EQ(app.eeprom_state(), static_cast<uint8_t>(proto::EepromState::kEmptyDefaults));
  CHECK_EQ(app.config().rate_hz, 500);
}

void TestBadEeprom() {
  auto b = MakeBoard();
  {
    App app(b->hal);
    app.Begin();
    proto::SetRate r = {};
    r.rate_hz = 100;
    b->Command(r);
    proto::SaveEeprom save;
    save.confirm = ja::app::kSaveConfirm;
    b->Command(save);
    b->Run(app, 100000);
    CHECK_EQ(app.eeprom_state(), static_cast<uint8_t>(proto::EepromState::kOk));
  }
  b->eeprom.bytes[ja::app::kEepromHeaderSize + 1] ^= 0x01;  // flip one bit of the payload
  b->ClearFrames();
  App app(b->hal);
  app.Begin();
  b->Flush();
  const uint8_t bad = static_cast<uint8_t>(proto::EepromState::kBadChecksumDefaults);
  CHECK_EQ(app.eeprom_state(), bad);
  CHECK_EQ(app.config().rate_hz, 500);  // defaults
  proto::Hello h;
  CHECK(b->Find(&h));
  CHECK_EQ(h.eeprom, bad);
  proto::Log log;
  CHECK(b->Find(&log));
  CHECK_EQ(log.level, static_cast<uint8_t>(proto::LogLevel::kWarning));
  b->Command(Stream(proto::stream_mode::kStatus, 100));
  b->Run(app, 50000);
  proto::Status st;
  CHECK(b->Last(&st));
  CHECK_EQ(st.eeprom, bad);
  b->Command(proto::StopStream());
  b->Run(app, 20000);

  // A newer layout is refused as such.
  b->eeprom.bytes[2] = ja::app::kEepromLayoutVersion + 1;
  App newer(b->hal);
  newer.Begin();
  CHECK_EQ(newer.eeprom_state(), static_cast<uint8_t>(proto::EepromState::kNewerLayoutDefaults));
  // A store whose writes do not stick: save_eeprom answers eeprom_failed.
  b->eeprom.broken = true;
  b->ClearFrames();
  proto::SaveEeprom save;
  save.confirm = ja::app::kSaveConfirm;
  const uint16_t q = b->Command(save);
  b->Run(newer, 5000);
  CHECK_EQ(b->AckError(proto::SaveEeprom::kId, q),
           static_cast<uint8_t>(proto::ErrorCode::kEepromFailed));
}

void TestStagedStoreIsCommitted() {
  // Writes wait until Commit (a flash sector): save_eeprom commits before its read-back, so the
  // save is acked ok and survives a virtual reset; a factory reset commits the erased header.
  auto b = MakeBoard();
  b->eeprom.staged = true;
  {
    App app(b->hal);
    app.Begin();
    proto::SetRate r = {};
    r.rate_hz = 200;
    b->Command(r);
    proto::SaveEeprom save;
    save.confirm = ja::app::kSaveConfirm;
    const uint16_t q = b->Command(save);
    b->Run(app, 100000);
    CHECK_EQ(b->AckError(proto::SaveEeprom::kId, q), 0);
    CHECK_EQ(b->eeprom.commits, 1u);
    CHECK(!b->eeprom.dirty);
  }
  App app(b->hal);
  app.Begin();
  CHECK_EQ(app.eeprom_state(), static_cast<uint8_t>(proto::EepromState::kOk));
  CHECK_EQ(app.config().rate_hz, 200);
  proto::Reset reset;
  reset.kind = static_cast<uint8_t>(proto::ResetKind::kFactoryDefaults);
  b->Command(reset);
  b->Run(app, 50000);
  CHECK_EQ(b->system.reboots, 1);
  CHECK_EQ(b->eeprom.commits, 2u);
  CHECK_EQ(app.eeprom_state(), static_cast<uint8_t>(proto::EepromState::kEmptyDefaults));
  // A commit that fails: save_eeprom answers eeprom_failed.
  b->eeprom.commit_fails = true;
  b->ClearFrames();
  proto::SaveEeprom save;
  save.confirm = ja::app::kSaveConfirm;
  const uint16_t q = b->Command(save);
  b->Run(app, 5000);
  CHECK_EQ(b->AckError(proto::SaveEeprom::kId, q),
           static_cast<uint8_t>(proto::ErrorCode::kEepromFailed));
}

}  // namespace

int main() {
  TestSlotsNotSetYet();
  TestEepromRoundTrip();
  TestBadEeprom();
  TestStagedStoreIsCommitted();
  return ja_test::Finish("test_app_eeprom");
}
