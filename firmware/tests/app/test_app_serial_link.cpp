// The application on x86 over in-test fakes, the serial link (APP.md "What a board implements":
// SerialPort; "Streaming"): the transmit ring; a stream larger than the link drops whole frames,
// counted, never a command's reply; the status still goes out at its interval.
#include <stdio.h>

#include <memory>

#include "app/tx_ring.hpp"
#include "app_test_helpers.hpp"
#include "check.hpp"

namespace {

namespace proto = ja::proto;
using ja::app::App;
using ja_test::Board;
using ja_test::MakeBoard;
using ja_test::Stream;

/// The default board on a link its stream does not fit: 200 kbaud (20 bytes/ms) while 70-byte
/// frames at 500 Hz need 35 bytes/ms, through the AVR's 256-byte transmit buffer.
std::unique_ptr<Board> MakeSaturatedLinkBoard() {
  auto b = MakeBoard();
  b->serial.capacity = 256;
  b->line_bytes_per_ms = 20;
  return b;
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

}  // namespace

int main() {
  TestTxRing();
  TestStatusIsNotStarvedByTheLeanStream();
  TestUartOverflowCounted();
  TestAcksSurviveASaturatedLink();
  TestStatusOnSaturatedLink();
  return ja_test::Finish("test_app_serial_link");
}
