// The application on x86 over in-test fakes, the loop and its timing (APP.md "The loop"): the
// filter's periods between grid slots, the 32-bit microsecond clock wrapping, overruns counted
// with frames kept on the grid, one command a Poll.
#include <stdio.h>

#include "app_test_helpers.hpp"
#include "check.hpp"

namespace {

namespace proto = ja::proto;
using ja::app::App;
using ja_test::kPi;
using ja_test::MakeBoard;
using ja_test::SetStaticPose;
using ja_test::Stream;
using ja_test::ThetaDeg;

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

}  // namespace

int main() {
  TestStepPeriods();
  TestClockWrap();
  TestOneCommandAPoll();
  TestLoopOverrunCounted();
  return ja_test::Finish("test_app_loop");
}
