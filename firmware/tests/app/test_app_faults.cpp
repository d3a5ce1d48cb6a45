// The application on x86 over in-test fakes, faults (APP.md "Faults"): each fault of each model
// flagged in the stream and counted in status while streaming continues, the estimate invalid
// meanwhile and re-initialised afterwards; a wrong ID at boot and while running; a failing
// multiplexer and one that loses its selection; a part that reset itself; frozen as a time.
#include <stdio.h>

#include "app_test_helpers.hpp"
#include "check.hpp"

namespace {

namespace proto = ja::proto;
namespace ss = proto::sensor_status;
namespace fh = proto::filter_health;
using ja::app::App;
using ja_test::Board;
using ja_test::kAdxl345;
using ja_test::kPi;
using ja_test::MakeBoard;
using ja_test::MakeMixedBoard;
using ja_test::SetMixedSensors;
using ja_test::SetStaticPose;
using ja_test::Stream;
using ja_test::ThetaDeg;

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

}  // namespace

int main() {
  TestFaults();
  TestFaultsOtherModels();
  TestWrongIdAtBoot();
  TestWrongIdWhileRunning();
  TestMuxFailure();
  TestMuxLosesSelection();
  TestFrozenIsATimeWhenTheLoopOverruns();
  TestSelfResetSensorIsProbedAgain();
  return ja_test::Finish("test_app_faults");
}
