// The pipelined sampling path (hal.hpp I2cBatch, the AVR board's): a batch is started every
// loop and never while another is in flight, frame k carries the reads started in loop k-1
// (one period of latency: loop k starts its batch into the other buffer before it processes
// batch k-1), a multiplexer whose select fails makes the read behind it a NACK without touching
// the bus, one select every SelectReadBackEvery loops is read back in turn, and commands in
// between leave the pipeline consistent.
#include <memory>

#include "app_fakes.hpp"
#include "app_test_helpers.hpp"
#include "check.hpp"

namespace {

namespace proto = ja::proto;
namespace ss = proto::sensor_status;
using ja::app::App;
using ja_test::Board;

constexpr uint8_t kAdxl345 = static_cast<uint8_t>(proto::SensorModel::kAdxl345);

std::unique_ptr<Board> MakeBoard() {
  std::unique_ptr<Board> b(new Board());  // large (frame log): not on the stack
  b->hal.batch = &b->batch;
  for (int ch = 0; ch < 4; ++ch) b->bus.Add(kAdxl345, 0x53, ch);
  return b;
}

/// Two ADXL345 a channel (ja_test::MakePairedBoard) over the batch.
std::unique_ptr<Board> MakePairedBoard() {
  auto b = ja_test::MakePairedBoard();
  b->hal.batch = &b->batch;
  return b;
}

proto::StartStream Stream(uint8_t mode) {
  proto::StartStream m = {};
  m.every = 1;
  m.mode = mode;
  m.status_interval_ms = 0;
  return m;
}

void TestOneBatchPerLoopNeverOverlapping() {
  auto b = MakeBoard();
  App app(b->hal);
  app.Begin();
  CHECK_EQ(b->batch.starts, 1u);  // Begin queues the first loop's reads
  b->Command(Stream(proto::stream_mode::kSampleEstimate));
  b->Run(app, 200000);
  CHECK_EQ(b->batch.overlapping, 0u);
  // One batch per loop, plus the one after Begin and the one restarted after the command.
  CHECK(b->batch.starts >= app.loops() && b->batch.starts <= app.loops() + 2);
  CHECK_EQ(app.loop_overruns(), 0);
  proto::SampleEstimate m;
  CHECK(b->Last(&m));
  for (int i = 0; i < 4; ++i) {
    CHECK_EQ(m.sensors[i].fresh, 1);
    CHECK_EQ(m.sensors[i].status, 0);
  }
}

void TestFrameCarriesPreviousLoopsRead() {
  auto b = MakeBoard();
  App app(b->hal);
  app.Begin();
  b->Command(Stream(proto::stream_mode::kSampleEstimate));
  b->Run(app, 20000);
  // Change the force on chip 0 between loops: the next frame still shows the old counts (read
  // one period earlier), the one after shows the new ones.
  proto::SampleEstimate before;
  CHECK(b->Last(&before));
  const int32_t old_x = before.sensors[0].x;
  b->bus.chips[0].force_mps2[0] = 5.0f;  // ~131 counts
  const int first = b->frame_count;
  b->Run(app, 4000);  // two loops
  proto::SampleEstimate f1, f2;
  CHECK(b->Find(&f1, 0, first));
  CHECK(b->Find(&f2, 1, first));
  CHECK(f1.sensors[0].x >= old_x - 2 && f1.sensors[0].x <= old_x + 2);  // +-1 count dither
  CHECK(f2.sensors[0].x > old_x + 100);
}

void TestMuxSelectFailureIsNack() {
  auto b = MakeBoard();
  App app(b->hal);
  app.Begin();
  b->Command(Stream(proto::stream_mode::kSampleEstimate));
  b->Run(app, 20000);
  const uint32_t reads = b->bus.chips[2].reads;
  b->bus.mux_nack = true;
  const int first = b->frame_count;
  b->Run(app, 6000);
  b->bus.mux_nack = false;
  proto::SampleEstimate m;
  CHECK(b->Find(&m, 2, first));
  for (int i = 0; i < 4; ++i) CHECK(m.sensors[i].status & ss::kNack);
  // While the select failed the sensors behind it were not read at all.
  CHECK(b->bus.chips[2].reads <= reads + 1);
  b->Run(app, 1200000);  // re-probed one per 250 ms
  CHECK(b->Last(&m));
  for (int i = 0; i < 4; ++i) CHECK_EQ(m.sensors[i].status, 0);
}

/// One multiplexer select a loop is read back, in turn; the others are plain writes. A mux that
/// ACKs every select but keeps its channel is caught on each sensor behind another channel within
/// a few loops.
void TestMuxSelectsVerifiedInTurn() {
  auto b = MakeBoard();
  App app(b->hal);
  app.Begin();
  b->Command(Stream(proto::stream_mode::kSampleEstimate));
  b->Run(app, 20000);
  const uint32_t readbacks = b->bus.mux_readbacks, writes = b->bus.mux_writes;
  const uint32_t loops = app.loops();
  b->Run(app, 200000);
  const uint32_t n = app.loops() - loops;
  CHECK(n >= 99 && n <= 101);
  // One read-back a loop (+ the driver's own select-and-verify before each periodic ID check,
  // one per 100 ms), three plain selects.
  CHECK(b->bus.mux_readbacks - readbacks >= n && b->bus.mux_readbacks - readbacks <= n + 3);
  CHECK(b->bus.mux_writes - writes >= 3 * n - 3 && b->bus.mux_writes - writes <= 3 * n + 3);

  b->bus.mux_stuck = true;
  const int first = b->frame_count;
  b->Run(app, 20000);  // ten loops
  bool flagged[4] = {false, false, false, false};
  proto::SampleEstimate m;
  for (int k = 0; b->Find(&m, k, first); ++k) {
    for (int i = 0; i < 4; ++i) flagged[i] = flagged[i] || (m.sensors[i].status & ss::kNack);
  }
  // Every sensor but the one on the channel the mux is stuck on (its reads are right).
  for (int i = 0; i < 4; ++i) CHECK_EQ(flagged[i], b->bus.mux_control != (1u << i));
  b->bus.mux_stuck = false;
  b->Run(app, 1200000);  // re-probed one per 250 ms
  CHECK(b->Last(&m));
  for (int i = 0; i < 4; ++i) CHECK_EQ(m.sensors[i].status, 0);
}

/// Each of twelve batches runs App::LoopSclPeriods() SCL periods when it reads a select back,
/// kReadBackSclPeriods less otherwise (the fake counts them per transfer the way a real bus
/// clocks them), every sensor read; one in `read_back_every` reads a select back.
void CheckBatchScl(Board& b, App& app, unsigned expected, unsigned read_back_every) {
  CHECK_EQ(app.LoopSclPeriods(), expected);
  unsigned read_backs = 0;
  for (int k = 0; k < 12; ++k) {
    b.Run(app, 1000000u / app.config().rate_hz);
    if (b.batch.last_scl == app.LoopSclPeriods()) {
      ++read_backs;
    } else {
      CHECK_EQ(b.batch.last_scl,
               static_cast<uint32_t>(app.LoopSclPeriods() - App::kReadBackSclPeriods));
    }
    for (uint8_t i = 0; i < app.config().sensor_count; ++i) {
      CHECK_EQ(app.sensor(i).status() & (ss::kNack | ss::kNotConfigured), 0);
    }
  }
  CHECK_EQ(read_backs, 12 / read_back_every);
}

/// The bus's bound on the rate (APP.md "Commands") counts the batch's SCL periods from the
/// configuration: the same layout BuildBatch builds and StartBatch runs, for each rig.
void TestLoopSclPeriodsAreTheBatchs() {
  {  // the factory rig: 3 x 20 + 39 (one select read back) + 4 x 84
    auto b = MakeBoard();
    App app(b->hal);
    app.Begin();
    CheckBatchScl(*b, app, 435, 1);  // 4 selects at 500 Hz: a read-back every loop
  }
  {  // two a channel (0x53, 0x1D): 20 + 39 + 4 x 84; 2 selects at 500 Hz: every other loop
    auto b = MakePairedBoard();
    App app(b->hal);
    ja_test::BeginPaired(*b, app);
    CheckBatchScl(*b, app, 395, 2);
  }
  {  // the mixed rig: an ADXL357's 9-byte read is 111
    auto b = ja_test::MakeMixedBoard();
    b->hal.batch = &b->batch;
    App app(b->hal);
    app.Begin();
    uint16_t q[2];
    ja_test::SetMixedSensors(*b, q);
    b->Run(app, 200000);
    CheckBatchScl(*b, app, 3 * 20 + 39 + 3 * 84 + 111, 1);
  }
  {  // link b on the bus itself (an ADXL345 at 0x1D, a BNO055): one all-off write, two selects
    auto b = MakeBoard();
    b->bus.Add(kAdxl345, 0x1D, -1);
    b->bus.Add(ja_test::kBno055, 0x28, -1);
    App app(b->hal);
    app.Begin();
    proto::SetSensor s = {};
    s.count = 4;
    s.link = 1;
    s.mux_channel = 255;
    s.range_g = 4;
    s.slot = 2;
    s.model = kAdxl345;
    s.address = 0x1D;
    s.x = 47500;
    b->Command(s);
    s.slot = 3;
    s.model = ja_test::kBno055;
    s.address = 0x28;
    s.x = 275000;
    b->Command(s);
    b->Run(app, 200000);
    CheckBatchScl(*b, app, 20 + 39 + 20 + 4 * 84, 2);  // 2 selects
  }
}

/// ApplyCalibration (fast path) against ApplyCalibrationWide (reference) on one map and sample:
/// adds 1 to *mismatches when they differ (either axis or the saturation bits), 1 to *saturated
/// when the reference saturates.
void CompareWithReference(const ja::app::CalibrationMap& map, const ja::drivers::RawSample& c,
                          int* mismatches, int* saturated) {
  uint16_t sat_fast = 0, sat_ref = 0;
  const ja::app::LinkReading f = ja::app::ApplyCalibration(map, c, &sat_fast);
  const ja::app::LinkReading r = ja::app::ApplyCalibrationWide(map, c, &sat_ref);
  *mismatches += f.x_q16 != r.x_q16 || f.y_q16 != r.y_q16 || sat_fast != sat_ref;
  *saturated += sat_ref != 0;
}

/// The 32 x 16-bit calibration path equals the 32 x 32-bit reference on random maps (from
/// random calibrations, so the precomputed base is the real one) and counts, at the extremes of
/// both, including saturating results.
void TestCalibrationPathsAgree() {
  uint32_t seed = 12345;
  auto next = [&seed]() {
    seed = seed * 1664525u + 1013904223u;
    return seed;
  };
  const int32_t edge_c[] = {32767, -32768, 32766, -32767, 1, -1, 0, 4095, -4096};
  int mismatches = 0, saturated = 0, runs = 0;
  for (int i = 0; i < 4000; ++i) {
    ja::app::SensorConfig s = {};
    s.model = static_cast<uint8_t>(proto::SensorModel::kBno055);  // 0.01 m/s^2 per count
    s.range_g = 16;
    s.rotation_urad = static_cast<int32_t>(next() % 6283185u);
    ja::app::Calibration k = {};
    for (int j = 0; j < 9; ++j) {
      // Large S sometimes (up to ~+-200 in Q24): results beyond Q15.16 saturate.
      k.s_q24[j] = (i % 5 == 0) ? static_cast<int32_t>(next()) >> 1
                                : static_cast<int32_t>(next() % 33554432u) - 16777216;
    }
    for (int j = 0; j < 3; ++j) k.o_umps2[j] = static_cast<int32_t>(next() % 2000001u) - 1000000;
    const ja::app::CalibrationMap map = ja::app::MakeCalibrationMap(s, k);
    if (map.saturated) continue;
    for (int n = 0; n < 50; ++n) {
      ja::drivers::RawSample c;
      int32_t* axes[3] = {&c.x, &c.y, &c.z};
      for (int32_t* a : axes) {
        *a = (n % 3 == 0) ? edge_c[next() % 9] : static_cast<int32_t>(next() % 65536u) - 32768;
      }
      CompareWithReference(map, c, &mismatches, &saturated);
      ++runs;
    }
  }
  CHECK_EQ(mismatches, 0);
  CHECK(runs > 50000);
  CHECK(saturated > 100);  // the saturating cases were exercised too
}

/// The fast path on counts in [-4096, 4095] (every ADXL345 sample) equals the reference on
/// maps of any coefficients and offsets (full int32 range, so both saturation directions) and
/// counts at and inside the edges of that range.
void TestSmallCountPathAgrees() {
  uint32_t seed = 777;
  auto next = [&seed]() {
    seed = seed * 1664525u + 1013904223u;
    return seed;
  };
  const int32_t edge_c[] = {4095, -4096, 4094, -4095, 1, -1, 0, 2048, -2048};
  const int32_t edge_m[] = {0x7FFFFFFF,  -0x7FFFFFFF - 1, 0x40000000, -0x40000000, 0x0000FFFF,
                            -0x00010000, 0x00008000,      1,          -1,          0};
  int mismatches = 0, saturated = 0, runs = 0;
  for (int i = 0; i < 20000; ++i) {
    ja::app::CalibrationMap map = {};
    for (int r = 0; r < 2; ++r) {
      for (int j = 0; j < 3; ++j) {
        map.m_q30[r][j] =
            (next() % 4 == 0) ? edge_m[next() % 10] : static_cast<int32_t>(next() ^ (next() << 7));
      }
      const uint32_t b = next();
      map.b_q16[r] =
          (i % 3 == 0) ? static_cast<int32_t>(b) : static_cast<int32_t>(b >> 8) - 8388608;
      // The constant of the offset-binary path, as MakeCalibrationMap forms it.
      const int64_t sum_m =
          static_cast<int64_t>(map.m_q30[r][0]) + map.m_q30[r][1] + map.m_q30[r][2];
      const uint64_t base =
          static_cast<uint64_t>(static_cast<int64_t>(map.b_q16[r]) * 16384 - sum_m * 32768);
      map.base_lo[r] = static_cast<uint32_t>(base);
      map.base_hi[r] = static_cast<int32_t>(static_cast<uint32_t>(base >> 32));
    }
    for (int n = 0; n < 10; ++n) {
      ja::drivers::RawSample c;
      int32_t* axes[3] = {&c.x, &c.y, &c.z};
      for (int32_t* a : axes) {
        *a = (n % 2 == 0) ? edge_c[next() % 9] : static_cast<int32_t>(next() % 8192u) - 4096;
      }
      CompareWithReference(map, c, &mismatches, &saturated);
      ++runs;
    }
  }
  CHECK_EQ(mismatches, 0);
  CHECK(runs == 200000);
  CHECK(saturated > 1000);
}

/// Read-backs are spaced by time, not loops (kSelectVerifyUs): 8 ms / (selects x period).
void TestSelectReadBackEvery() {
  using ja::app::SelectReadBackEvery;
  CHECK_EQ(SelectReadBackEvery(4, 2000), 1);  // the factory rig at 500 Hz: every loop
  CHECK_EQ(SelectReadBackEvery(4, 4000), 1);  // ... and slower (a channel every 4 loops)
  CHECK_EQ(SelectReadBackEvery(4, 1250), 1);  // 800 Hz: 5 ms a round
  CHECK_EQ(SelectReadBackEvery(2, 1000), 4);  // two a channel at 1 kHz: a channel every 8 ms
  CHECK_EQ(SelectReadBackEvery(2, 1052), 3);  // 950 Hz
  CHECK_EQ(SelectReadBackEvery(1, 1000), 8);
  CHECK_EQ(SelectReadBackEvery(0, 1000), 1);  // no selects: nothing to space
  CHECK_EQ(SelectReadBackEvery(1, 10), 255);  // (clamped)
}

/// Two ADXL345 a channel at 1 kHz: a select read back one loop in four (two channels, each every
/// 8 ms), and a multiplexer stuck on one channel is still caught on every sensor behind the
/// other within kSelectVerifyUs and a loop.
void TestReadBacksSpacedAtOneKilohertz() {
  auto b = MakePairedBoard();
  App app(b->hal);
  ja_test::BeginPaired(*b, app);
  proto::SetRate r = {};
  r.rate_hz = 1000;
  b->Command(r);
  b->Command(Stream(proto::stream_mode::kSampleEstimate));
  b->Run(app, 20000);
  CHECK_EQ(app.config().rate_hz, 1000);
  const uint32_t readbacks = b->bus.mux_readbacks, writes = b->bus.mux_writes;
  const uint32_t loops = app.loops();
  b->Run(app, 200000);
  const uint32_t n = app.loops() - loops;
  CHECK(n >= 199 && n <= 201);
  // n / 4 read-backs (+ the driver's own select-and-verify before each periodic ID check).
  CHECK(b->bus.mux_readbacks - readbacks >= n / 4 && b->bus.mux_readbacks - readbacks <= n / 4 + 3);
  CHECK(b->bus.mux_writes - writes >= 2 * n - n / 4 - 1);
  CHECK_EQ(app.loop_overruns(), 0);

  b->bus.mux_stuck = true;
  const int first = b->frame_count;
  b->Run(app, ja::app::kSelectVerifyUs + 2000);
  bool flagged[4] = {false, false, false, false};
  proto::SampleEstimate m;
  for (int k = 0; b->Find(&m, k, first); ++k) {
    for (int i = 0; i < 4; ++i) flagged[i] = flagged[i] || (m.sensors[i].status & ss::kNack);
  }
  const int stuck_channel = b->bus.mux_control == 1u ? 0 : 1;
  for (int i = 0; i < 4; ++i) CHECK_EQ(flagged[i], i / 2 != stuck_channel);
  b->bus.mux_stuck = false;
}

}  // namespace

int main() {
  TestSelectReadBackEvery();
  TestReadBacksSpacedAtOneKilohertz();
  TestCalibrationPathsAgree();
  TestSmallCountPathAgrees();
  TestOneBatchPerLoopNeverOverlapping();
  TestFrameCarriesPreviousLoopsRead();
  TestMuxSelectFailureIsNack();
  TestMuxSelectsVerifiedInTurn();
  TestLoopSclPeriodsAreTheBatchs();
  return ja_test::Finish("test_app_batch");
}
