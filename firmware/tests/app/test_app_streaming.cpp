// The application on x86 over in-test fakes, streaming (APP.md "Streaming"): 500 frames/s with
// consecutive seq 2000 us apart and every sensor fresh, the static pose estimated; samples and
// estimate at another rate; the lean stream and decimation; the analytical kind; too few sensors.
#include "app_test_helpers.hpp"
#include "check.hpp"

namespace {

namespace proto = ja::proto;
namespace fh = proto::filter_health;
using ja::app::App;
using ja_test::kAdxl345;
using ja_test::kPi;
using ja_test::MakeBoard;
using ja_test::SetStaticPose;
using ja_test::Stream;
using ja_test::ThetaDeg;

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

}  // namespace

int main() {
  TestStreamingAtRate();
  TestRateAndSamplesEstimate();
  TestLeanStreamAndDecimation();
  TestTooFewSensors();
  TestAnalyticalSkipsEkf();
  return ja_test::Finish("test_app_streaming");
}
