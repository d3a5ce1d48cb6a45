// The application on x86 over in-test fakes (app_fakes.hpp): hello, streaming at the configured
// rate with fresh samples, every command's ack or nack, EEPROM persistence across a virtual
// reset, bad EEPROM, each sensor fault flagged while streaming continues, UART drops, overruns.
#include <math.h>
#include <stdio.h>

#include <memory>

#include "app/tx_ring.hpp"
#include "app_fakes.hpp"
#include "check.hpp"

namespace {

namespace proto = ja::proto;
namespace ss = proto::sensor_status;
namespace fh = proto::filter_health;
using ja::app::App;
using ja_test::Board;

constexpr uint8_t kAdxl345 = static_cast<uint8_t>(proto::SensorModel::kAdxl345);
constexpr uint8_t kAdxl357 = static_cast<uint8_t>(proto::SensorModel::kAdxl357);
constexpr uint8_t kBno055 = static_cast<uint8_t>(proto::SensorModel::kBno055);
constexpr float kG = 9.80665f;
constexpr double kPi = 3.14159265358979;

std::unique_ptr<Board> MakeBoard() {
  std::unique_ptr<Board> b(new Board());
  b->AddDefaultChips();
  return b;
}

/// The mixed rig: ADXL345s (0x53) on channels 0 and 2, an ADXL357 (0x1D) on 1, a BNO055 (0x28)
/// on 3.
std::unique_ptr<Board> MakeMixedBoard() {
  std::unique_ptr<Board> b(new Board());
  b->bus.Add(kAdxl345, 0x53, 0);
  b->bus.Add(kAdxl357, 0x1D, 1);
  b->bus.Add(kAdxl345, 0x53, 2);
  b->bus.Add(kBno055, 0x28, 3);
  return b;
}

/// set_sensor for an ADXL345 wired to the bus itself (no multiplexer channel).
proto::SetSensor DirectAdxl345(uint8_t slot, uint8_t count, uint8_t link, uint8_t address,
                               uint8_t range_g, int32_t x_um) {
  proto::SetSensor s = {};
  s.slot = slot;
  s.count = count;
  s.link = link;
  s.model = kAdxl345;
  s.mux_channel = ja::app::kNoMux;
  s.address = address;
  s.range_g = range_g;
  s.x = x_um;
  return s;
}

/// Commands the mixed rig's slots 1 (ADXL357, +-10 g, link a) and 3 (BNO055, +-4 g, link b);
/// the two commands' seqs in q.
void SetMixedSensors(Board& b, uint16_t q[2]) {
  proto::SetSensor s = {};
  s.slot = 1;
  s.count = 4;
  s.link = 0;
  s.model = kAdxl357;
  s.mux_channel = 1;
  s.address = 0x1D;
  s.range_g = 10;
  s.x = 275000;
  q[0] = b.Command(s);
  s.slot = 3;
  s.link = 1;
  s.model = kBno055;
  s.mux_channel = 3;
  s.address = 0x28;
  s.range_g = 4;
  q[1] = b.Command(s);
}

proto::StartStream Stream(uint8_t mode, uint16_t status_ms = 0) {
  proto::StartStream m = {};
  m.every = 1;
  m.mode = mode;
  m.status_interval_ms = status_ms;
  return m;
}

/// Static pose with gravity in the plane: link a's sensors read f_a, link b's R(theta)^T f_a.
void SetStaticPose(Board& b, double theta_rad) {
  const float fa[2] = {0.6f * kG, 0.8f * kG};
  const float c = static_cast<float>(cos(theta_rad)), s = static_cast<float>(sin(theta_rad));
  const float fb[2] = {c * fa[0] - s * fa[1], s * fa[0] + c * fa[1]};
  for (int i = 0; i < 4; ++i) {
    const float* f = i < 2 ? fa : fb;
    b.bus.chips[i].force_mps2[0] = f[0];
    b.bus.chips[i].force_mps2[1] = f[1];
    b.bus.chips[i].force_mps2[2] = 0.1f * kG;
  }
}

double ThetaDeg(const proto::SampleEstimate& m) { return m.theta / 16777216.0 * 180.0 / kPi; }

void TestHelloAtBoot() {
  auto b = MakeBoard();
  App app(b->hal);
  app.Begin();
  b->Flush();
  proto::Hello h;
  CHECK(b->Find(&h));
  CHECK_EQ(b->frames[0].header.msg_id, proto::Hello::kId);
  CHECK_EQ(b->frames[0].header.seq, 0);
  CHECK_EQ(h.protocol_version, proto::kProtocolVersion);
  CHECK_EQ(h.schema_hash, proto::kSchemaHash);
  CHECK_EQ(h.firmware_major, ja::app::kFirmwareMajor);
  CHECK_EQ(h.firmware_minor, ja::app::kFirmwareMinor);
  CHECK_EQ(h.board, static_cast<uint8_t>(proto::Board::kNative));
  CHECK_EQ(h.sample_rate_hz, 500);
  CHECK_EQ(h.eeprom, static_cast<uint8_t>(proto::EepromState::kEmptyDefaults));
  CHECK_EQ(h.sensors_count, 4);
  for (int i = 0; i < 4; ++i) {
    CHECK_EQ(h.sensors[i].model, kAdxl345);
    CHECK_EQ(h.sensors[i].chip_id, 0xE5);
    CHECK_EQ(h.sensors[i].mux_channel, i);
    CHECK_EQ(h.sensors[i].address, 0x53);
    CHECK_EQ(h.sensors[i].link, i < 2 ? 0 : 1);
    CHECK_EQ(h.sensors[i].status, 0);
  }
  CHECK_EQ(b->decoder.stats().crc_errors, 0u);
  CHECK_EQ(b->decoder.stats().malformed, 0u);

  // get_info: a hello, then the ack.
  b->ClearFrames();
  const uint16_t seq = b->Command(proto::GetInfo());
  b->Run(app, 1000);
  CHECK_EQ(b->frame_count, 2);
  CHECK_EQ(b->frames[0].header.msg_id, proto::Hello::kId);
  CHECK_EQ(b->AckError(proto::GetInfo::kId, seq), 0);
}

void TestInventoryReadsChipIds() {
  auto b = MakeMixedBoard();
  App app(b->hal);
  app.Begin();
  uint16_t q[2];
  SetMixedSensors(*b, q);
  b->Run(app, 100000);
  CHECK_EQ(b->AckError(proto::SetSensor::kId, q[0]), 0);
  CHECK_EQ(b->AckError(proto::SetSensor::kId, q[1]), 0);
  b->ClearFrames();
  b->Command(proto::GetInfo());
  b->Run(app, 1000);
  proto::Hello h;
  CHECK(b->Find(&h));
  CHECK_EQ(h.sensors[1].model, kAdxl357);
  CHECK_EQ(h.sensors[1].chip_id, 0xED);
  CHECK_EQ(h.sensors[1].range_g, 10);
  CHECK_EQ(h.sensors[3].model, kBno055);
  CHECK_EQ(h.sensors[3].chip_id, 0xA0);
  for (int i = 0; i < 4; ++i) CHECK_EQ(h.sensors[i].status, 0);
  // The ADXL357 was configured for +-10 g and a 1 kHz ODR (>= 1.6 x 500 Hz); the BNO055 is in
  // ACCONLY after the datasheet's mode-switch waits.
  CHECK_EQ(b->bus.chips[1].regs[0x2C] & 3, 1);
  CHECK_EQ(b->bus.chips[1].regs[0x28] & 0xF, 2);
  CHECK_EQ(b->bus.chips[3].regs[0x3D], 0x01);
  CHECK(b->delay.total_ms >= 28);
  // All four stream with fresh samples (the BNO055's value changes every read here).
  b->ClearFrames();
  b->Command(Stream(proto::stream_mode::kSampleEstimate));
  b->Run(app, 100000);
  proto::SampleEstimate m;
  CHECK(b->Last(&m));
  CHECK_EQ(m.sensors_count, 4);
  for (int i = 0; i < 4; ++i) {
    CHECK_EQ(m.sensors[i].fresh, 1);
    CHECK_EQ(m.sensors[i].status, 0);
  }
}

void TestSensorOnRootBus() {
  // mux_channel 255: the sensor is reached without the multiplexer (here the multiplexer NACKs
  // throughout: only that sensor works; switching every channel off before its reads NACKs too,
  // which counts as no channel on).
  std::unique_ptr<Board> b(new Board());
  b->bus.Add(kAdxl345, 0x1D, -1);
  b->bus.mux_nack = true;
  App app(b->hal);
  app.Begin();
  const uint16_t q = b->Command(DirectAdxl345(0, 4, 0, 0x1D, 2, 47500));
  b->Command(Stream(proto::stream_mode::kSampleEstimate));
  b->Run(app, 100000);
  CHECK_EQ(b->AckError(proto::SetSensor::kId, q), 0);
  proto::SampleEstimate m;
  CHECK(b->Last(&m));
  CHECK_EQ(m.sensors[0].status, 0);
  CHECK_EQ(m.sensors[0].fresh, 1);
  for (int i = 1; i < 4; ++i) CHECK(m.sensors[i].status & ss::kNack);
  CHECK_EQ(b->bus.chips[0].regs[0x31], 0x08);  // full resolution, +-2 g
}

/// A sensor on the bus itself at the address of the parts behind the multiplexer: every channel
/// is switched off before it is read, so the direct part answers, not the channel's (with the
/// last channel left on, the muxed part answered every read of the direct slot).
void TestDirectSensorBesideMuxedOnesOfItsAddress() {
  std::unique_ptr<Board> b(new Board());
  b->AddDefaultChips();  // 0x53 on channels 0-3
  ja_test::FakeChip& direct = b->bus.Add(kAdxl345, 0x53, -1);
  for (int i = 0; i < 4; ++i) b->bus.chips[i].force_mps2[0] = 1.0f;
  direct.force_mps2[0] = -5.0f;
  App app(b->hal);
  app.Begin();
  const uint16_t q = b->Command(DirectAdxl345(4, 5, 1, 0x53, 4, 100000));
  b->Run(app, 200000);
  CHECK_EQ(b->AckError(proto::SetSensor::kId, q), 0);
  fprintf(stderr, "direct 0x53 beside muxed 0x53: counts.x %d (direct part -5 m/s^2), muxed %d\n",
          static_cast<int>(app.sensor(4).counts().x), static_cast<int>(app.sensor(0).counts().x));
  CHECK_EQ(app.sensor(4).status() & (ss::kNack | ss::kWrongId | ss::kNotConfigured), 0);
  CHECK(app.sensor(4).counts().x < -100);                            // -5 m/s^2 = -131 counts
  for (int i = 0; i < 4; ++i) CHECK(app.sensor(i).counts().x > 20);  // +1 m/s^2 = 26
}

void TestStreamingAtRate() {
  auto b = MakeBoard();
  SetStaticPose(*b, 0.5);
  App app(b->hal);
  app.Begin();
  b->Run(app, 10000);
  b->ClearFrames();
  const uint16_t seq =
      b->Command(Stream(proto::stream_mode::kSampleEstimate | proto::stream_mode::kStatus, 100));
  b->Run(app, 1000000);
  CHECK_EQ(b->AckError(proto::StartStream::kId, seq), 0);
  const int n = b->Count<proto::SampleEstimate>();
  CHECK(n >= 499 && n <= 501);
  const int status = b->Count<proto::Status>();
  CHECK(status >= 10 && status <= 12);
  CHECK_EQ(b->decoder.stats().frames_lost, 0u);
  CHECK_EQ(app.uart_drops(), 0);
  CHECK_EQ(app.loop_overruns(), 0);
  // Consecutive sample_estimate frames are one period (2000 us) apart; every sensor fresh.
  uint32_t last_t = 0;
  int checked = 0;
  for (int i = 0; i < b->frame_count; ++i) {
    if (b->frames[i].header.msg_id != proto::SampleEstimate::kId) continue;
    proto::SampleEstimate m;
    CHECK(m.decode(b->frames[i].payload, b->frames[i].size));
    CHECK_EQ(m.sensors_count, 4);
    for (int k = 0; k < 4; ++k) {
      CHECK_EQ(m.sensors[k].fresh, 1);
      CHECK_EQ(m.sensors[k].status, 0);
    }
    if (checked++ > 0) CHECK_EQ(b->frames[i].header.t_us - last_t, 2000u);
    last_t = b->frames[i].header.t_us;
  }
  // The raw counts are the chip's: 0.6 g on x is ~154 counts at 3.9 mg/LSB.
  proto::SampleEstimate m;
  CHECK(b->Last(&m));
  CHECK(m.sensors[0].x >= 152 && m.sensors[0].x <= 156);
  // The estimate: static pose at 0.5 rad, found from gravity.
  CHECK(m.health & fh::kRunning);
  CHECK_NEAR(ThetaDeg(m), 0.5 * 180.0 / kPi, 1.0);
  // Loop statistics cover a whole 1 s window: run past the next status frame.
  b->Run(app, 300000);
  proto::Status st;
  CHECK(b->Last(&st));
  CHECK_EQ(st.loop_rate_hz, 500);
  CHECK_EQ(st.sensors_count, 4);
  CHECK_EQ(st.eeprom, static_cast<uint8_t>(proto::EepromState::kEmptyDefaults));
  CHECK(st.uptime_ms >= 1200);
  CHECK(st.idle_permille >= 990);  // the fake bus costs no time

  // stop_stream: no more periodic frames.
  b->ClearFrames();
  const uint16_t stop = b->Command(proto::StopStream());
  b->Run(app, 100000);
  CHECK_EQ(b->AckError(proto::StopStream::kId, stop), 0);
  CHECK(b->Count<proto::SampleEstimate>() <= 1);
}

void TestClockWrap() {
  auto b = MakeBoard();
  b->clock.now_us = 0xFFFFFFFFu - 300000u;  // the 32-bit microsecond clock wraps after 0.3 s
  SetStaticPose(*b, 0.2);
  App app(b->hal);
  app.Begin();
  b->Command(Stream(proto::stream_mode::kSampleEstimate | proto::stream_mode::kStatus, 100));
  b->Run(app, 1300000);
  const int n = b->Count<proto::SampleEstimate>();
  CHECK(n >= 649 && n <= 651);
  CHECK_EQ(app.loop_overruns(), 0);
  CHECK_EQ(b->decoder.stats().frames_lost, 0u);
  proto::Status st;
  CHECK(b->Last(&st));
  CHECK(st.uptime_ms >= 1200 && st.uptime_ms <= 1300);
  CHECK_EQ(st.loop_rate_hz, 500);
  proto::SampleEstimate m;
  CHECK(b->Last(&m));
  CHECK_NEAR(ThetaDeg(m), 0.2 * 180.0 / kPi, 1.0);
}

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

/// The board measures what it holds (status sustainable_rate_hz: 0.8 s of work a second at the
/// last second's busy time a loop, 10 Hz steps) and refuses set_rate above it, naming it in the
/// ack's detail, unless force; at or below it, or forced, the rate is taken.
void TestSetRateAboveTheSustainableRateIsRefused() {
  auto b = MakeBoard();
  App app(b->hal);
  app.Begin();
  b->bus.us_per_transaction = 250;  // ~2 ms of bus work a loop: a few hundred Hz at most
  b->Command(Stream(proto::stream_mode::kStatus, 100));
  b->Run(app, 2500000);
  proto::Status st;
  CHECK(b->Last(&st));
  const uint16_t held = st.sustainable_rate_hz;
  fprintf(stderr, "sustainable %u Hz at %u Hz, %u permille asleep\n", static_cast<unsigned>(held),
          static_cast<unsigned>(st.loop_rate_hz), static_cast<unsigned>(st.idle_permille));
  CHECK(held >= 10 && held < 500 && held % 10 == 0);
  b->Command(proto::StopStream());
  b->Run(app, 10000);
  proto::SetRate r = {};
  r.rate_hz = static_cast<uint16_t>(held + 10);
  const uint16_t refused = b->Command(r);
  r.rate_hz = held;
  const uint16_t taken = b->Command(r);
  b->Run(app, 300000);  // set_rate probes every sensor again: slow on this bus
  proto::Ack ack = {};
  bool found = false;
  for (int i = 0; b->Find(&ack, i); ++i) {
    if (ack.command_seq == refused) {
      found = true;
      break;
    }
  }
  CHECK(found);
  CHECK_EQ(ack.error, static_cast<uint8_t>(proto::ErrorCode::kRateNotSustainable));
  CHECK_EQ(ack.detail, held);
  CHECK_EQ(b->AckError(proto::SetRate::kId, taken), 0);
  CHECK_EQ(app.config().rate_hz, held);
  r.rate_hz = 1000;
  r.force = 1;
  const uint16_t forced = b->Command(r);
  b->Run(app, 300000);  // set_rate probes every sensor again: slow on this bus
  CHECK_EQ(b->AckError(proto::SetRate::kId, forced), 0);
  CHECK_EQ(app.config().rate_hz, 1000);
  r.force = 2;
  const uint16_t bad = b->Command(r);
  b->Run(app, 300000);  // set_rate probes every sensor again: slow on this bus
  CHECK_EQ(b->AckError(proto::SetRate::kId, bad),
           static_cast<uint8_t>(proto::ErrorCode::kBadValue));
}

void TestRateAndSamplesEstimate() {
  auto b = MakeBoard();
  SetStaticPose(*b, -1.0);
  App app(b->hal);
  app.Begin();
  proto::SetRate r = {};
  r.rate_hz = 200;
  const uint16_t q = b->Command(r);
  b->Run(app, 1000);
  CHECK_EQ(b->AckError(proto::SetRate::kId, q), 0);
  // ADXL345 ODR follows: >= 1.6 x 200 Hz -> 400 Hz (code 0x0C).
  CHECK_EQ(b->bus.chips[0].regs[0x2C], 0x0C);
  b->ClearFrames();
  b->Command(Stream(proto::stream_mode::kSamples | proto::stream_mode::kEstimate));
  b->Run(app, 500000);
  const int ns = b->Count<proto::Samples>(), ne = b->Count<proto::Estimate>();
  CHECK(ns >= 99 && ns <= 101);
  CHECK_EQ(ns, ne);
  proto::Estimate e;
  CHECK(b->Last(&e));
  CHECK_NEAR(e.theta / 16777216.0, -1.0, 0.02);
  CHECK_NEAR(e.theta_analytical / 16777216.0, -1.0, 0.02);
  CHECK(e.p_trace > 0);
  CHECK(e.health & fh::kRunning);
  CHECK_EQ(b->Count<proto::SampleEstimate>(), 0);
}
/// On a link the lean stream saturates (500 Hz x 27 bytes over 115 200 baud) the status still
/// goes out every interval: a due status that does not fit holds back that loop's lean frame, so
/// the room builds up for it (before, the smaller lean frame took every byte freed and the status
/// never fitted again: `info --rates --stream estimates` at 115 200 baud read no rates).
void TestStatusIsNotStarvedByTheLeanStream() {
  auto b = MakeBoard();
  App app(b->hal);
  app.Begin();
  b->Run(app, 300000);
  b->line_bytes_per_ms = 11;  // 115 200 baud, 10 bits a byte (11.52)
  b->Command(Stream(proto::stream_mode::kLeanEstimate | proto::stream_mode::kStatus, 200));
  b->Run(app, 100000);
  b->ClearFrames();
  b->Run(app, 2000000);
  const int statuses = b->Count<proto::Status>();
  const int lean = b->Count<proto::LeanEstimate>();
  fprintf(stderr, "saturated lean stream: %d status, %d lean_estimate frames in 2 s\n", statuses,
          lean);
  CHECK(statuses >= 9);
  CHECK(lean >= 700);           // the link's room, less the statuses'
  CHECK(app.uart_drops() > 0);  // saturated indeed
}

/// The lean stream (StreamMode.lean_estimate: the estimate, health and a fault mask, 15 bytes)
/// and start_stream's `every`: at 500 Hz and every = 4, ~125 lean frames a second with
/// consecutive seq; sample_estimate with every = 2 at half the loop rate; every = 0 refused.
void TestLeanStreamAndDecimation() {
  auto b = MakeBoard();
  SetStaticPose(*b, -1.0);
  App app(b->hal);
  app.Begin();
  b->Run(app, 300000);
  proto::StartStream lean = Stream(proto::stream_mode::kLeanEstimate);
  lean.every = 4;
  b->Command(lean);
  b->Run(app, 20000);
  b->ClearFrames();
  b->Run(app, 1000000);
  const int n = b->Count<proto::LeanEstimate>();
  CHECK(n >= 123 && n <= 127);
  CHECK_EQ(b->Count<proto::SampleEstimate>(), 0);
  proto::LeanEstimate m;
  CHECK(b->Last(&m));
  CHECK_NEAR(m.theta / 16777216.0, -1.0, 0.02);
  CHECK(m.health & fh::kRunning);
  CHECK_EQ(m.faulty, 0);
  // The frames' seq are consecutive: the host counts losses as with the full frame.
  uint16_t last = 0;
  bool consecutive = true, first = true;
  for (int i = 0; i < b->frame_count; ++i) {
    if (b->frames[i].header.msg_id != proto::LeanEstimate::kId) continue;
    const uint16_t seq = b->frames[i].header.seq;
    if (!first && seq != static_cast<uint16_t>(last + 1)) consecutive = false;
    last = seq;
    first = false;
  }
  CHECK(consecutive);
  b->Command(proto::StopStream());
  proto::StartStream full = Stream(proto::stream_mode::kSampleEstimate);
  full.every = 2;
  b->Command(full);
  b->Run(app, 20000);
  b->ClearFrames();
  b->Run(app, 1000000);
  const int f = b->Count<proto::SampleEstimate>();
  CHECK(f >= 248 && f <= 252);
  full.every = 0;
  const uint16_t bad = b->Command(full);
  b->Run(app, 20000);
  CHECK_EQ(b->AckError(proto::StartStream::kId, bad),
           static_cast<uint8_t>(proto::ErrorCode::kBadValue));
}

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
  CHECK_EQ(ja::app::SaturationCounts(kAdxl345, 2), 511);
  CHECK_EQ(ja::app::SaturationCounts(kAdxl345, 16), 4095);
  CHECK_EQ(ja::app::SaturationCounts(kBno055, 4), 3921);
}

void TestCommandsAckAndNack() {
  auto b = MakeBoard();
  App app(b->hal);
  app.Begin();
  using E = proto::ErrorCode;
  struct Case {
    uint8_t id;
    uint16_t seq;
    E expected;
  };
  Case cases[48];
  int n = 0;
  auto expect = [&](uint8_t id, uint16_t seq, E e) { cases[n++] = Case{id, seq, e}; };

  expect(proto::StartStream::kId, b->Command(Stream(0)), E::kBadValue);
  expect(proto::StartStream::kId, b->Command(Stream(0x80)), E::kBadValue);
  proto::SetRate r = {};
  r.rate_hz = 5;
  expect(proto::SetRate::kId, b->Command(r), E::kBadValue);
  r.rate_hz = 2000;
  expect(proto::SetRate::kId, b->Command(r), E::kBadValue);
  r.rate_hz = 400;
  expect(proto::SetRate::kId, b->Command(r), E::kOk);
  proto::SetJoint j = {};
  j.link = 2;
  expect(proto::SetJoint::kId, b->Command(j), E::kBadValue);
  j.link = 1;
  j.x = 300000;
  expect(proto::SetJoint::kId, b->Command(j), E::kOk);
  j.x = 20000000;
  expect(proto::SetJoint::kId, b->Command(j), E::kBadValue);
  proto::SetSensor s = {};
  s.slot = 4;
  s.count = 4;
  s.model = kAdxl345;
  s.range_g = 2;
  s.address = 0x53;
  expect(proto::SetSensor::kId, b->Command(s), E::kBadValue);  // slot >= count
  s.slot = 0;
  s.count = 12;
  expect(proto::SetSensor::kId, b->Command(s), E::kUnsupported);  // > 8 slots
  s.count = 4;
  s.range_g = 3;
  expect(proto::SetSensor::kId, b->Command(s), E::kBadValue);  // no such range
  s.range_g = 2;
  s.model = 9;
  expect(proto::SetSensor::kId, b->Command(s), E::kBadValue);
  s.model = kAdxl345;
  s.mux_channel = 8;
  expect(proto::SetSensor::kId, b->Command(s), E::kBadValue);
  proto::SetCalibration c = {};
  c.slot = 4;
  expect(proto::SetCalibration::kId, b->Command(c), E::kBadValue);
  c.slot = 0;  // S all zero: singular
  expect(proto::SetCalibration::kId, b->Command(c), E::kBadCalibration);
  c.s00 = c.s11 = c.s22 = INT32_MAX;  // absurd entries
  expect(proto::SetCalibration::kId, b->Command(c), E::kBadCalibration);
  c.s00 = c.s11 = c.s22 = 1 << 24;
  c.s01 = c.s10 = 1 << 24;  // rows 0 and 1 equal: det 0
  expect(proto::SetCalibration::kId, b->Command(c), E::kBadCalibration);
  c.s01 = c.s10 = 0;
  c.oz = 60000000;  // 60 m/s^2 offset
  expect(proto::SetCalibration::kId, b->Command(c), E::kBadCalibration);
  c.oz = -200000;  // a plausible one: accepted
  expect(proto::SetCalibration::kId, b->Command(c), E::kOk);
  c.oz = 0;
  c.slot = 4;
  proto::SetFilter f = {};
  f.kind = 3;
  expect(proto::SetFilter::kId, b->Command(f), E::kBadValue);
  f.kind = 0;
  f.flags = 1;
  expect(proto::SetFilter::kId, b->Command(f), E::kBadValue);
  f.flags = 0;
  f.p0 = 2 * 65536;
  expect(proto::SetFilter::kId, b->Command(f), E::kUnsupported);
  f.p0 = 65536;
  f.accel_sigma = 50;  // 50 um/s^2: below any accelerometer's noise
  expect(proto::SetFilter::kId, b->Command(f), E::kBadNoise);
  f.accel_sigma = 20000000;  // 20 m/s^2
  expect(proto::SetFilter::kId, b->Command(f), E::kBadNoise);
  f.accel_sigma = 0;  // from the datasheet
  expect(proto::SetFilter::kId, b->Command(f), E::kOk);
  f.accel_sigma = 50000;
  expect(proto::SetFilter::kId, b->Command(f), E::kOk);
  proto::SaveEeprom save;
  save.confirm = 0x1234;
  expect(proto::SaveEeprom::kId, b->Command(save), E::kBadValue);
  proto::Reset reset;
  reset.kind = 7;
  expect(proto::Reset::kId, b->Command(reset), E::kBadValue);
  // While streaming: bus reconfiguration and EEPROM writes are refused; calibration is not.
  expect(proto::StartStream::kId, b->Command(Stream(proto::stream_mode::kSampleEstimate)), E::kOk);
  r.rate_hz = 250;
  expect(proto::SetRate::kId, b->Command(r), E::kNotAllowedWhileStreaming);
  j.x = 0;
  expect(proto::SetJoint::kId, b->Command(j), E::kNotAllowedWhileStreaming);
  s.mux_channel = 0;
  expect(proto::SetSensor::kId, b->Command(s), E::kNotAllowedWhileStreaming);
  save.confirm = ja::app::kSaveConfirm;
  expect(proto::SaveEeprom::kId, b->Command(save), E::kNotAllowedWhileStreaming);
  c.slot = 0;
  c.s00 = c.s11 = c.s22 = 1 << 24;
  expect(proto::SetCalibration::kId, b->Command(c), E::kOk);
  expect(proto::StopStream::kId, b->Command(proto::StopStream()), E::kOk);
  b->Run(app, 20000);

  // Unknown ids and wrong payload lengths, framed by hand.
  uint8_t buf[proto::kMaxFrameBytes];
  const uint8_t payload[3] = {1, 2, 3};
  const proto::FrameHeader unknown = {proto::kProtocolVersion, 0x4F, 900, 0};
  size_t len = proto::encode_frame(unknown, payload, 0, buf, sizeof buf);
  b->serial.Inject(buf, len);
  const proto::FrameHeader device_msg = {proto::kProtocolVersion, proto::Hello::kId, 901, 0};
  len = proto::encode_frame(device_msg, payload, 0, buf, sizeof buf);
  b->serial.Inject(buf, len);
  const proto::FrameHeader short_rate = {proto::kProtocolVersion, proto::SetRate::kId, 902, 0};
  len = proto::encode_frame(short_rate, payload, 1, buf, sizeof buf);
  b->serial.Inject(buf, len);
  const proto::FrameHeader long_info = {proto::kProtocolVersion, proto::GetInfo::kId, 903, 0};
  len = proto::encode_frame(long_info, payload, 3, buf, sizeof buf);
  b->serial.Inject(buf, len);
  b->Run(app, 10000);
  expect(0x4F, 900, E::kUnknownCommand);
  expect(proto::Hello::kId, 901, E::kUnknownCommand);
  expect(proto::SetRate::kId, 902, E::kBadLength);
  expect(proto::GetInfo::kId, 903, E::kBadLength);

  for (int i = 0; i < n; ++i) {
    const uint8_t got = b->AckError(cases[i].id, cases[i].seq);
    if (!CHECK_EQ(got, static_cast<uint8_t>(cases[i].expected))) {
      fprintf(stderr, "  case %d: command 0x%02X seq %u: ack %u, expected %u\n", i, cases[i].id,
              cases[i].seq, got, static_cast<unsigned>(cases[i].expected));
    }
  }
  CHECK_EQ(app.config().rate_hz, 400);
  CHECK_EQ(app.config().joint_um[1][0], 300000);
  CHECK_EQ(app.config().filter.accel_sigma_u, 50000u);
  CHECK_EQ(app.config().calibration[0].s_q24[0], 1 << 24);
  // Exactly one ack per command: nothing answered twice.
  CHECK_EQ(b->Count<proto::Ack>(), n);
}

void TestRxErrorsCounted() {
  auto b = MakeBoard();
  App app(b->hal);
  app.Begin();
  const uint8_t garbage[] = {0x13, 0x37, 0x00, 0x42, 0x99, 0x12, 0x55, 0x00};
  b->serial.Inject(garbage, sizeof garbage);
  uint8_t buf[proto::kMaxFrameBytes];
  proto::GetInfo info;
  size_t len = proto::encode_message(info, 7, 0, buf, sizeof buf);
  buf[3] ^= 0x10;  // corrupt: CRC error
  b->serial.Inject(buf, len);
  const uint16_t seq = b->Command(Stream(proto::stream_mode::kStatus, 50));
  b->Run(app, 60000);
  CHECK_EQ(b->AckError(proto::StartStream::kId, seq), 0);
  proto::Status st;
  CHECK(b->Last(&st));
  CHECK(st.rx_errors >= 3);
}

/// A command in another protocol version is answered with hello in ours (a host of another
/// version can then name both), and counted as a receive error.
void TestOtherVersionGetsHello() {
  auto b = MakeBoard();
  App app(b->hal);
  app.Begin();
  b->Run(app, 10000);
  b->ClearFrames();
  uint8_t buf[proto::kMaxFrameBytes];
  const proto::FrameHeader other = {static_cast<uint8_t>(proto::kProtocolVersion + 1),
                                    proto::GetInfo::kId, 9, 0};
  const size_t len = proto::finish_frame(other, 0, buf, sizeof buf);
  CHECK(len > 0);
  b->serial.Inject(buf, len);
  b->Run(app, 10000);
  proto::Hello h;
  CHECK(b->Find(&h));
  CHECK_EQ(h.protocol_version, proto::kProtocolVersion);
  CHECK_EQ(b->Count<proto::Ack>(), 0);  // not a command of ours: no ack
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

/// Streams 1 s with a fault applied to sensor `victim` after 0.3 s and cleared after 0.7 s.
struct FaultRun {
  uint8_t bits_during = 0;       // sensor status bits seen while the fault was on (OR)
  uint8_t bits_after = 0xFF;     // in the last frame
  uint8_t health_during = 0xFF;  // AND over the frames while the fault was on (after 0.3 s)
  bool reset_after = false;
  int frames = 0;
  proto::Status status;
  proto::SampleEstimate last;
};

template <class Apply>
FaultRun RunFault(Board& b, App& app, int victim, Apply&& apply) {
  FaultRun out;
  b.Command(Stream(proto::stream_mode::kSampleEstimate));
  b.Run(app, 300000);
  apply(b.bus.chips[victim], true);
  const int from = b.frame_count;
  b.Run(app, 400000);
  for (int i = from; i < b.frame_count; ++i) {
    if (b.frames[i].header.msg_id != proto::SampleEstimate::kId) continue;
    proto::SampleEstimate m;
    m.decode(b.frames[i].payload, b.frames[i].size);
    out.bits_during |= m.sensors[victim].status;
    if (i > from + 150) out.health_during &= m.health;
  }
  apply(b.bus.chips[victim], false);
  const int after = b.frame_count;
  b.Run(app, 700000);
  b.Last(&out.last);
  out.bits_after = out.last.sensors[victim].status;
  for (int i = after; i < b.frame_count; ++i) {
    if (b.frames[i].header.msg_id != proto::SampleEstimate::kId) continue;
    proto::SampleEstimate m;
    m.decode(b.frames[i].payload, b.frames[i].size);
    if (m.health & fh::kReset) out.reset_after = true;
  }
  out.frames = b.Count<proto::SampleEstimate>();
  b.Last(&out.status);
  return out;
}

void TestFaults() {
  struct Kind {
    const char* name;
    uint8_t bit;
    void (*apply)(ja_test::FakeChip&, bool);
  };
  const Kind kinds[] = {
      {"nack", ss::kNack, [](ja_test::FakeChip& c, bool on) { c.nack = on; }},
      {"saturated", ss::kSaturated, [](ja_test::FakeChip& c, bool on) { c.saturate = on; }},
      {"frozen", ss::kFrozen, [](ja_test::FakeChip& c, bool on) { c.frozen = on; }},
      {"wrong_id", ss::kWrongId,
       [](ja_test::FakeChip& c, bool on) {
         // Another part answers after a dropout: one NACK, then the wrong ID on re-probe.
         c.regs[0x00] = on ? 0x42 : 0xE5;
         c.nack_next = on ? 1 : 0;
       }},
  };
  for (const Kind& k : kinds) {
    auto b = MakeBoard();
    SetStaticPose(*b, 0.3);
    App app(b->hal);
    app.Begin();
    const FaultRun r = RunFault(*b, app, 1, k.apply);
    fprintf(stderr, "fault %s: during 0x%02X after 0x%02X health 0x%02X frames %d\n", k.name,
            r.bits_during, r.bits_after, r.health_during, r.frames);
    CHECK(r.bits_during & k.bit);
    CHECK_EQ(r.bits_after & (ss::kNack | ss::kWrongId | ss::kSaturated | ss::kFrozen), 0);
    // The stream never stopped: 1.4 s at 500 Hz.
    CHECK(r.frames >= 699);
    // Link a lost a sensor: the estimate is marked invalid while the fault lasts...
    CHECK_EQ(r.health_during & fh::kRunning, 0);
    // ...and re-initialised once it cleared, back on the right angle.
    CHECK(r.reset_after);
    CHECK(r.last.health & fh::kRunning);
    CHECK_NEAR(ThetaDeg(r.last), 0.3 * 180.0 / kPi, 1.0);
    // Counted, and reported in the status frames sent on each change.
    const proto::StatusSensor& s = r.status.sensors[1];
    if (k.bit == ss::kNack) CHECK(s.nacks >= 1);
    if (k.bit == ss::kSaturated) CHECK(s.saturations >= 1);
    if (k.bit == ss::kFrozen) CHECK_EQ(s.freezes, 1);
    if (k.bit == ss::kWrongId) CHECK(s.id_errors >= 1);
    CHECK_EQ(r.status.sensors[1].status & (ss::kNack | ss::kWrongId | ss::kSaturated | ss::kFrozen),
             0);
    CHECK_EQ(r.status.sensors[0].nacks + r.status.sensors[0].saturations, 0);
  }
}

/// Saturation and frozen output of the other two models, on a mixed rig.
void TestFaultsOtherModels() {
  auto b = MakeMixedBoard();
  App app(b->hal);
  app.Begin();
  uint16_t q[2];
  SetMixedSensors(*b, q);
  b->Run(app, 100000);
  for (int victim : {1, 3}) {
    for (int fault = 0; fault < 2; ++fault) {
      b->ClearFrames();
      const FaultRun r = RunFault(*b, app, victim, [&](ja_test::FakeChip& c, bool on) {
        if (fault == 0) c.saturate = on;
        if (fault == 1) c.frozen = on;
      });
      const uint8_t bit = fault == 0 ? ss::kSaturated : ss::kFrozen;
      fprintf(stderr, "model %u fault 0x%02X: during 0x%02X after 0x%02X\n",
              b->bus.chips[victim].model, bit, r.bits_during, r.bits_after);
      CHECK(r.bits_during & bit);
      CHECK_EQ(r.bits_after & (ss::kSaturated | ss::kFrozen), 0);
      CHECK(r.frames >= 699);
    }
  }
}

/// A part that resets by itself (a supply glitch) keeps its ID but stops measuring: its output
/// freezes, the periodic check finds it out of its measuring mode, and a probe configures it
/// again, so the filter comes back without a command. Every model, on the mixed rig too.
void TestSelfResetSensorIsProbedAgain() {
  for (int mixed = 0; mixed < 2; ++mixed) {
    auto b = mixed ? MakeMixedBoard() : MakeBoard();
    if (!mixed) SetStaticPose(*b, 0.3);
    App app(b->hal);
    app.Begin();
    if (mixed) {
      uint16_t q[2];
      SetMixedSensors(*b, q);
    }
    b->Command(Stream(proto::stream_mode::kSampleEstimate));
    b->Run(app, 500000);
    for (int victim : {1, 3}) {
      ja_test::FakeChip& chip = b->bus.chips[victim];
      const uint8_t ch = static_cast<uint8_t>(chip.channel);
      chip.Reset();  // power-on register values: standby / CONFIG mode, same ID
      CHECK(!chip.Measuring());
      b->Run(app, 300000);
      CHECK(app.sensor(victim).status() & ss::kFrozen);
      b->Run(app, 2000000);  // ID checks every 100 ms in turn, a probe every 250 ms
      fprintf(stderr,
              "model %u (channel %u) reset itself: measuring %d, status 0x%02X, "
              "health 0x%02X\n",
              chip.model, ch, chip.Measuring(), app.sensor(victim).status(), app.health());
      CHECK(chip.Measuring());
      CHECK_EQ(app.sensor(victim).status() & (ss::kFrozen | ss::kNotConfigured), 0);
      CHECK(app.health() & fh::kRunning);
    }
  }
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

/// Fewer sensors than the filter needs: streamed, flagged invalid, never stepped.
void TestTooFewSensors() {
  auto b = MakeBoard();
  App app(b->hal);
  app.Begin();
  proto::SetSensor s = {};
  s.slot = 0;
  s.count = 3;
  s.model = kAdxl345;
  s.address = 0x53;
  s.range_g = 4;
  s.x = 47500;
  const uint16_t q = b->Command(s);
  b->Command(Stream(proto::stream_mode::kSampleEstimate));
  b->Run(app, 100000);
  CHECK_EQ(b->AckError(proto::SetSensor::kId, q), 0);
  proto::SampleEstimate m;
  CHECK(b->Last(&m));
  CHECK_EQ(m.sensors_count, 3);
  CHECK_EQ(m.health & fh::kRunning, 0);
  CHECK_EQ(m.theta, 0);
  CHECK(!app.filter_valid());
  CHECK_EQ(app.filter_state().health.steps, 0u);
}

void TestWrongIdWhileRunning() {
  // The part keeps answering and streaming, but its ID register changes (another part): the
  // periodic ID check flags it without any NACK.
  auto b = MakeBoard();
  SetStaticPose(*b, 0.3);
  App app(b->hal);
  app.Begin();
  b->Command(Stream(proto::stream_mode::kSampleEstimate));
  b->Run(app, 300000);
  b->bus.chips[2].regs[0x00] = 0x1A;
  b->Run(app, 500000);  // 4 sensors x 100 ms
  proto::SampleEstimate m;
  CHECK(b->Last(&m));
  CHECK(m.sensors[2].status & ss::kWrongId);
  CHECK_EQ(m.sensors[2].status & ss::kNack, 0);
  CHECK_EQ(m.health & fh::kRunning, 0);
  CHECK_EQ(app.sensor(2).chip_id(), 0x1A);
  b->bus.chips[2].regs[0x00] = 0xE5;
  b->Run(app, 1000000);
  CHECK(b->Last(&m));
  CHECK_EQ(m.sensors[2].status, 0);
  CHECK(m.health & fh::kRunning);
  CHECK_EQ(app.sensor(2).chip_id(), 0xE5);
  CHECK_EQ(app.loop_overruns(), 0);
}

void TestBnoBootWait() {
  // A BNO055 NACKs for its ~650 ms power-up boot: Begin keeps probing before the hello; a part
  // that never answers costs the 700 ms once and is reported.
  std::unique_ptr<Board> b(new Board());
  b->bus.Add(kAdxl345, 0x53, 0);
  ja_test::FakeChip& bno = b->bus.Add(kBno055, 0x28, 1);
  bno.nack_next = 1000000;  // silent until released below
  // Configure slot 1 as a BNO055 in EEPROM (the app reads its rig from there at boot).
  ja::app::Config c;
  ja::app::SetDefaults(c);
  c.sensor_count = 2;
  c.sensors[1].model = kBno055;
  c.sensors[1].address = 0x28;
  c.sensors[1].mux_channel = 1;
  CHECK(ja::app::SaveConfig(b->eeprom, c));
  struct Releaser final : ja::drivers::Delay {
    ja_test::FakeClock* clock;
    ja_test::FakeChip* chip;
    uint32_t total_ms = 0;
    void WaitMs(uint16_t ms) override {
      clock->now_us += 1000u * ms;
      total_ms += ms;
      if (total_ms >= 600) chip->nack_next = 0;  // booted
    }
  } releaser;
  releaser.clock = &b->clock;
  releaser.chip = &bno;
  ja::app::Hal hal{b->bus, releaser, b->clock, b->serial, b->eeprom, b->system, 2};
  App app(hal);
  app.Begin();
  b->Flush();
  proto::Hello h;
  CHECK(b->Find(&h));
  CHECK_EQ(h.sensors[1].chip_id, 0xA0);
  CHECK_EQ(h.sensors[1].status, 0);
  CHECK(releaser.total_ms >= 600 && releaser.total_ms <= 700);
  // Never answers: 700 ms, then NACK in the hello.
  bno.nack_next = 1000000;
  releaser.total_ms = 0;
  releaser.chip = &b->bus.chips[15];  // release nothing
  b->ClearFrames();
  App again(hal);
  again.Begin();
  b->Flush();
  CHECK(b->Find(&h));
  CHECK(h.sensors[1].status & ss::kNack);
  CHECK_EQ(releaser.total_ms, 700u);
}

void TestWrongIdAtBoot() {
  auto b = MakeBoard();
  b->bus.chips[2].regs[0x00] = 0x00;
  b->bus.chips[3].nack = true;
  App app(b->hal);
  app.Begin();
  b->Flush();
  proto::Hello h;
  CHECK(b->Find(&h));
  CHECK_EQ(h.sensors[2].chip_id, 0x00);
  CHECK(h.sensors[2].status & ss::kWrongId);
  CHECK(h.sensors[3].status & ss::kNack);
  CHECK_EQ(h.sensors[3].chip_id, 0);
  b->Command(Stream(proto::stream_mode::kSampleEstimate));
  b->Run(app, 200000);
  proto::SampleEstimate m;
  CHECK(b->Last(&m));
  CHECK(m.sensors[2].status & ss::kWrongId);
  CHECK_EQ(m.health & fh::kRunning, 0);
  CHECK_EQ(m.sensors[0].status, 0);
  CHECK_EQ(m.sensors[0].fresh, 1);
  // Both parts come back: re-probed (one per 250 ms), the estimate runs again.
  b->bus.chips[2].regs[0x00] = 0xE5;
  b->bus.chips[3].nack = false;
  b->Run(app, 1000000);
  CHECK(b->Last(&m));
  CHECK_EQ(m.sensors[2].status, 0);
  CHECK_EQ(m.sensors[3].status, 0);
  CHECK(m.health & fh::kRunning);
}

void TestMuxFailure() {
  auto b = MakeBoard();
  App app(b->hal);
  app.Begin();
  b->Command(Stream(proto::stream_mode::kSampleEstimate));
  b->Run(app, 100000);
  b->bus.mux_nack = true;
  const int from = b->frame_count;
  b->Run(app, 200000);
  CHECK(b->Count<proto::SampleEstimate>(from) >= 99);
  proto::SampleEstimate m;
  CHECK(b->Last(&m));
  for (int i = 0; i < 4; ++i) CHECK(m.sensors[i].status & ss::kNack);
  b->bus.mux_nack = false;
  b->Run(app, 1500000);
  CHECK(b->Last(&m));
  for (int i = 0; i < 4; ++i) CHECK_EQ(m.sensors[i].status, 0);
}

void TestMuxLosesSelection() {
  // The multiplexer resets (control register 0) while the app believes a channel is selected:
  // the sensors NACK, the app re-selects, everything recovers.
  auto b = MakeBoard();
  App app(b->hal);
  app.Begin();
  proto::SetSensor s = {};
  s.count = 2;  // two sensors on one channel: the selection is cached between loops
  s.link = 0;
  s.model = kAdxl345;
  s.mux_channel = 0;
  s.address = 0x53;
  s.range_g = 4;
  s.x = 47500;
  b->Command(s);
  b->bus.Add(kAdxl345, 0x1D, 0);
  s.slot = 1;
  s.address = 0x1D;
  s.x = 275000;
  b->Command(s);
  b->Run(app, 10000);
  b->Command(Stream(proto::stream_mode::kSampleEstimate));
  b->Run(app, 100000);
  proto::SampleEstimate m;
  CHECK(b->Last(&m));
  CHECK_EQ(m.sensors_count, 2);
  CHECK_EQ(m.sensors[1].status, 0);
  const uint32_t selects_before = b->bus.transactions;
  b->bus.mux_control = 0;
  b->Run(app, 1000000);
  CHECK(b->Last(&m));
  for (int i = 0; i < 2; ++i) {
    CHECK_EQ(m.sensors[i].status, 0);
    CHECK_EQ(m.sensors[i].fresh, 1);
  }
  CHECK(b->bus.transactions > selects_before);
}

/// The default board on a link its stream does not fit: 200 kbaud (20 bytes/ms) while 70-byte
/// frames at 500 Hz need 35 bytes/ms, through the AVR's 256-byte transmit buffer.
std::unique_ptr<Board> MakeSaturatedLinkBoard() {
  auto b = MakeBoard();
  b->serial.capacity = 256;
  b->line_bytes_per_ms = 20;
  return b;
}

void TestUartOverflowCounted() {
  auto b = MakeSaturatedLinkBoard();
  App app(b->hal);
  app.Begin();
  b->Command(Stream(proto::stream_mode::kSampleEstimate | proto::stream_mode::kStatus, 100));
  b->Run(app, 1000000);
  b->Flush();
  CHECK(app.uart_drops() > 0);
  CHECK_EQ(b->serial.overflow_writes, 0u);  // never more than TxFree()
  CHECK(b->decoder.stats().frames_lost > 0);
  CHECK_EQ(b->decoder.stats().crc_errors, 0u);  // whole frames dropped, never half a frame
  CHECK_EQ(b->decoder.stats().malformed, 0u);
  proto::Status st;
  CHECK(b->Last(&st));
  CHECK(st.uart_drops > 0);
  CHECK_EQ(app.loop_overruns(), 0);  // the loop itself kept its rate
  CHECK(app.loops() >= 499);
}

// A stream larger than the link drops its own frames, never the reply to a command: a command
// waits for room for its replies (ReplyRoom) and the stream leaves it that room.
void TestAcksSurviveASaturatedLink() {
  auto b = MakeSaturatedLinkBoard();
  App app(b->hal);
  app.Begin();
  b->Command(Stream(proto::stream_mode::kSampleEstimate | proto::stream_mode::kStatus, 100));
  b->Run(app, 200000);
  uint16_t seqs[100];
  for (uint16_t& q : seqs) {
    q = b->Command(proto::RestartFilter());
    b->Run(app, 3100);  // every 3.1 ms, out of step with the 2 ms loop
  }
  b->Run(app, 50000);
  int acked = 0;
  for (const uint16_t q : seqs) acked += b->AckError(proto::RestartFilter::kId, q) == 0 ? 1 : 0;
  fprintf(stderr, "saturated link: %d of 100 restart_filter acks, uart_drops %u\n", acked,
          static_cast<unsigned>(app.uart_drops()));
  CHECK(app.uart_drops() > 0);  // the link was saturated throughout
  CHECK_EQ(acked, 100);
  // A command with a longer reply waits for room for it too: every calibration and its ack.
  b->ClearFrames();
  proto::GetCalibration get;
  get.slot = 1;
  get.source = static_cast<uint8_t>(proto::CalibrationSource::kRunning);
  uint16_t gets[20];
  for (uint16_t& q : gets) {
    q = b->Command(get);
    b->Run(app, 3100);
  }
  b->Run(app, 50000);
  int answered = 0;
  for (const uint16_t q : gets) answered += b->AckError(proto::GetCalibration::kId, q) == 0;
  CHECK_EQ(answered, 20);
  CHECK_EQ(b->Count<proto::Calibration>(), 20);
}

// Commands queued faster than they are handled: one a Poll, so the loop (and a board's watchdog
// kick between Polls) is not held up by the whole queue.
void TestOneCommandAPoll() {
  auto b = MakeBoard();
  App app(b->hal);
  app.Begin();
  b->Run(app, 100000);
  b->bus.us_per_transaction = 100;
  proto::SetRate r = {};
  r.rate_hz = 500;
  r.force = 1;  // this slow bus does not hold it: the point here is the queue
  uint16_t seqs[12];
  for (uint16_t& q : seqs) q = b->Command(r);  // each probes all four sensors again
  const uint32_t t0 = b->clock.now_us;
  app.Poll();
  const uint32_t one_us = b->clock.now_us - t0;
  b->Flush();
  const bool first = b->AckError(proto::SetRate::kId, seqs[0]) == 0;
  const bool second = b->AckError(proto::SetRate::kId, seqs[1]) != 255;
  b->Run(app, 200000);
  int acked = 0;
  for (const uint16_t q : seqs) acked += b->AckError(proto::SetRate::kId, q) == 0 ? 1 : 0;
  fprintf(stderr,
          "one Poll with 12 set_rate queued: %u us of bus work, first acked %d, "
          "second %d; %d acked in all\n",
          static_cast<unsigned>(one_us), first, second, acked);
  CHECK(one_us > 0);
  CHECK(first);
  CHECK(!second);  // still queued after the first Poll
  CHECK_EQ(acked, 12);
}

// A saturated link drops sample frames every loop; the periodic status must still go out at its
// interval (it used to lose its turn: the interval restarted even when the frame was dropped).
void TestStatusOnSaturatedLink() {
  auto b = MakeSaturatedLinkBoard();
  App app(b->hal);
  app.Begin();
  b->Command(Stream(proto::stream_mode::kSampleEstimate | proto::stream_mode::kStatus, 100));
  b->Run(app, 20000);
  b->Flush();
  const int from = b->frame_count;
  b->Run(app, 1000000);
  b->Flush();
  CHECK(app.uart_drops() > 0);
  const int status_frames = b->Count<proto::Status>(from);
  CHECK(status_frames >= 9 && status_frames <= 11);  // every 100 ms for 1 s
  CHECK(b->Count<proto::SampleEstimate>(from) > 100);
  CHECK_EQ(b->decoder.stats().crc_errors, 0u);
}

// restart_filter: acked, the next frame has health reset (steps counted from 1 again), and the
// settings are the ones set before (here kind analytical, sigma 40 000 ug) - nothing changes.
void TestRestartFilterKeepsSettings() {
  auto b = MakeBoard();
  SetStaticPose(*b, 1.0);
  App app(b->hal);
  app.Begin();
  proto::SetFilter f = {};
  f.kind = static_cast<uint8_t>(proto::FilterKind::kAnalytical);
  f.accel_sigma = 40000;
  b->Command(f);
  b->Command(Stream(proto::stream_mode::kSampleEstimate));
  b->Run(app, 100000);
  CHECK(app.filter_state().health.steps >= 49);
  const int from = b->frame_count;
  const uint16_t q = b->Command(proto::RestartFilter());
  b->Run(app, 20000);
  CHECK_EQ(b->AckError(proto::RestartFilter::kId, q), 0);
  CHECK(app.filter_state().health.steps < 15);
  proto::SampleEstimate m;
  bool reset = false;
  for (int k = 0; b->Find(&m, k, from); ++k) reset = reset || (m.health & fh::kReset) != 0;
  CHECK(reset);
  CHECK_EQ(app.config().filter.kind, static_cast<uint8_t>(proto::FilterKind::kAnalytical));
  CHECK_EQ(app.config().filter.accel_sigma_u, 40000u);
  CHECK(b->Last(&m));
  CHECK_NEAR(ThetaDeg(m), 1.0 * 180.0 / kPi, 0.5);
}

// Filter kind analytical: eq. 12 only; the EKF does not run (it used to step in full, ~36k
// cycles on the AVR, and its result was thrown away).
void TestAnalyticalSkipsEkf() {
  auto b = MakeBoard();
  SetStaticPose(*b, 1.0);
  App app(b->hal);
  app.Begin();
  proto::SetFilter f = {};
  f.kind = static_cast<uint8_t>(proto::FilterKind::kAnalytical);
  const uint16_t q = b->Command(f);
  b->Command(Stream(proto::stream_mode::kSampleEstimate | proto::stream_mode::kEstimate));
  b->Run(app, 100000);
  CHECK_EQ(b->AckError(proto::SetFilter::kId, q), 0);
  CHECK(!app.filter_state().initialised);  // core::Step never ran
  CHECK(app.filter_state().health.steps >= 49);
  proto::SampleEstimate m;
  CHECK(b->Last(&m));
  CHECK(m.health & fh::kRunning);
  CHECK_EQ(m.omega_a, 0);
  CHECK_NEAR(ThetaDeg(m), 1.0 * 180.0 / kPi, 0.5);
  proto::Estimate e;
  CHECK(b->Last(&e));
  CHECK_EQ(e.theta_analytical, m.theta);
  // Back to the EKF: it restarts and runs.
  f.kind = static_cast<uint8_t>(proto::FilterKind::kEkf);
  b->Command(proto::StopStream());
  b->Command(f);
  b->Run(app, 20000);
  CHECK(app.filter_state().initialised);
}

void TestLoopOverrunCounted() {
  auto b = MakeBoard();
  App app(b->hal);
  app.Begin();
  b->Command(Stream(proto::stream_mode::kSampleEstimate | proto::stream_mode::kStatus, 200));
  b->Run(app, 100000);
  CHECK_EQ(app.loop_overruns(), 0);
  b->bus.us_per_transaction = 300;  // 4 x (select + read) = 2.4 ms > the 2 ms period
  b->Run(app, 1500000);
  CHECK(app.loop_overruns() > 100);
  proto::Status st;
  CHECK(b->Last(&st));
  CHECK(st.loop_overruns > 100);
  // 2.4 ms of work a loop at a 2 ms period: the next loop starts at once, as fast as the work
  // allows (~415 a second, never half the 500 asked), with no time asleep.
  fprintf(stderr, "overloaded loop: %u Hz, %u permille idle\n",
          static_cast<unsigned>(st.loop_rate_hz), static_cast<unsigned>(st.idle_permille));
  CHECK(st.loop_rate_hz >= 380 && st.loop_rate_hz <= 440);
  CHECK(st.idle_permille < 150);  // (was ~400 while a late loop waited for the next free slot)
  // Stamped on the 2 ms grid, the last slot at or before each start: gaps of one or two periods
  // whose mean is the real loop time, so the filter's time (the slots) keeps up with the clock.
  int gaps = 0, twos = 0;
  uint32_t first = 0, last = 0, prev = 0;
  for (int i = 0; i < b->frame_count; ++i) {
    if (b->frames[i].header.msg_id != proto::SampleEstimate::kId) continue;
    const uint32_t t = b->frames[i].header.t_us;
    if (t < 200000) continue;  // the overload starts at 0.1 s
    if (prev != 0) {
      const uint32_t gap = t - prev;
      CHECK(gap == 2000 || gap == 4000);
      twos += gap == 4000;
      ++gaps;
    } else {
      first = t;
    }
    prev = last = t;
  }
  CHECK(gaps > 400);
  const double mean_gap_us = static_cast<double>(last - first) / gaps;
  fprintf(stderr, "mean gap %.1f us, %d of %d gaps two periods\n", mean_gap_us, twos, gaps);
  CHECK(mean_gap_us > 2300 && mean_gap_us < 2500);
  CHECK(twos > gaps / 10 && twos < gaps / 3);
}

/// Frozen is a time (kFrozenSeconds = 0.2 s), not a number of loops: with the loop overrunning
/// (a loop every 2.4 ms at a 2 ms period, stamped on the grid) an unchanged output is flagged
/// 0.2 s after it froze, not 0.24 s (as a count in loops would).
void TestFrozenIsATimeWhenTheLoopOverruns() {
  auto b = MakeBoard();
  SetStaticPose(*b, 0.3);
  App app(b->hal);
  app.Begin();
  b->Command(Stream(proto::stream_mode::kSampleEstimate));
  b->bus.us_per_transaction = 300;  // 2.4 ms of bus work a loop: one loop per 2.4 ms
  b->Run(app, 300000);
  CHECK(app.loop_overruns() > 50);
  const int from = b->frame_count;
  uint32_t t0 = 0, flagged_at = 0;
  for (int i = from - 1; i >= 0 && t0 == 0; --i) {
    if (b->frames[i].header.msg_id == proto::SampleEstimate::kId) t0 = b->frames[i].header.t_us;
  }
  b->bus.chips[1].frozen = true;
  b->Run(app, 600000);
  for (int i = from; i < b->frame_count && flagged_at == 0; ++i) {
    if (b->frames[i].header.msg_id != proto::SampleEstimate::kId) continue;
    proto::SampleEstimate m;
    m.decode(b->frames[i].payload, b->frames[i].size);
    if (m.sensors[1].status & ss::kFrozen) flagged_at = b->frames[i].header.t_us;
  }
  CHECK(flagged_at != 0);
  const uint32_t after_us = flagged_at - t0;
  fprintf(stderr, "frozen flagged %u us after the output froze (loop every 2.4 ms)\n",
          static_cast<unsigned>(after_us));
  // 0.2 s of unchanged output, plus the pipelined read and one loop of rounding.
  CHECK(after_us >= 190000 && after_us <= 220000);
}

void TestStepPeriods() {
  using ja::app::StepPeriods;
  CHECK_EQ(StepPeriods(2000, 2000), 1);
  CHECK_EQ(StepPeriods(0, 2000), 1);     // at least 1 (a timing reset)
  CHECK_EQ(StepPeriods(2999, 2000), 1);  // round half up: 1.4995 -> 1
  CHECK_EQ(StepPeriods(3000, 2000), 2);
  CHECK_EQ(StepPeriods(4000, 2000), 2);
  CHECK_EQ(StepPeriods(6998, 2000), 3);
  CHECK_EQ(StepPeriods(15000, 2000), 8);
  CHECK_EQ(StepPeriods(16000, 2000), 8);        // clamped
  CHECK_EQ(StepPeriods(0xFFFFFFFFu, 2000), 8);  // no overflow
  CHECK_EQ(StepPeriods(3333 * 3, 3333), 3);     // 300 Hz: period 3333 us
}

void TestTxRing() {
  ja::app::TxRing ring;
  CHECK_EQ(ring.Free(), 255);
  uint8_t data[200];
  for (int i = 0; i < 200; ++i) data[i] = static_cast<uint8_t>(i * 7);
  uint32_t sent = 0, got = 0;
  uint8_t expect = 0, b = 0;
  bool in_order = true;
  // Many wraps of the one-byte indices: write when a block fits, drain a little each round.
  for (int round = 0; round < 2000; ++round) {
    const uint16_t n = static_cast<uint16_t>(1 + (round * 37) % 120);
    if (ring.Free() >= n) {
      for (uint16_t i = 0; i < n; ++i) data[i] = static_cast<uint8_t>(sent + i);
      ring.Write(data, n);
      sent += n;
    }
    for (int k = 0; k < 50 && ring.Pop(&b); ++k, ++got) {
      in_order = in_order && b == expect;
      ++expect;
    }
    CHECK_EQ(ring.Free() + ring.Used(), 255);
  }
  while (ring.Pop(&b)) {
    in_order = in_order && b == expect;
    ++expect;
    ++got;
  }
  CHECK(in_order);
  CHECK_EQ(got, sent);
  CHECK(sent > 50000);
  ring.Write(data, 200);
  ring.Write(data, 100);  // does not fit: ignored whole
  CHECK_EQ(ring.Used(), 200);
}

}  // namespace

int main() {
  TestStepPeriods();
  TestTxRing();
  TestHelloAtBoot();
  TestInventoryReadsChipIds();
  TestSensorOnRootBus();
  TestDirectSensorBesideMuxedOnesOfItsAddress();
  TestStreamingAtRate();
  TestRateAndSamplesEstimate();
  TestSetRateAboveTheSustainableRateIsRefused();
  TestLeanStreamAndDecimation();
  TestStatusIsNotStarvedByTheLeanStream();
  TestClockWrap();
  TestSlotsNotSetYet();
  TestMountingRotationAndCalibration();
  TestCalibrationMap();
  TestCommandsAckAndNack();
  TestRxErrorsCounted();
  TestOtherVersionGetsHello();
  TestEepromRoundTrip();
  TestGetCalibration();
  TestBadEeprom();
  TestFaults();
  TestFaultsOtherModels();
  TestTooFewSensors();
  TestWrongIdAtBoot();
  TestBnoBootWait();
  TestWrongIdWhileRunning();
  TestMuxFailure();
  TestMuxLosesSelection();
  TestUartOverflowCounted();
  TestAcksSurviveASaturatedLink();
  TestOneCommandAPoll();
  TestStatusOnSaturatedLink();
  TestAnalyticalSkipsEkf();
  TestRestartFilterKeepsSettings();
  TestLoopOverrunCounted();
  TestFrozenIsATimeWhenTheLoopOverruns();
  TestSelfResetSensorIsProbedAgain();
  TestUnusableCalibrationIsFlagged();
  return ja_test::Finish("test_app");
}
