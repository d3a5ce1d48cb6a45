// libFuzzer target for the byte-wise frame decoder and the generated message codecs.
// Built with clang -fsanitize=fuzzer,address,undefined by tests/cpp/protocol/CMakeLists.txt and run
// for a bounded number of inputs by ctest (protocol_fuzz_decoder). Any crash, sanitizer report or
// abort() below is a failure. For each input:
//  1. feed it byte by byte: never crash; every accepted frame whose payload decodes as its
//     message must re-encode to the same bytes; the counters stay consistent;
//  2. frame the input itself (first byte = msg id, rest = payload) and decode it back: exactly
//     that frame must come out, also when preceded by the input as garbage.
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "protocol/frame.hpp"
#include "protocol/messages.hpp"

namespace {

using ja::proto::DecodeEvent;
using ja::proto::FrameDecoder;

template <class Msg>
void round_trip(const uint8_t* payload, size_t n) {
  Msg msg;
  if (!msg.decode(payload, n)) return;
  uint8_t out[ja::proto::kMaxPayload];
  size_t len = 0;
  if (!msg.encode(out, sizeof out, &len) || len != n || memcmp(out, payload, n) != 0) abort();
}

void check_payload(uint8_t id, const uint8_t* payload, size_t n) {
  switch (id) {
#define JA_FUZZ_CASE(Type, msg_id, name)     \
  case msg_id:                               \
    round_trip<ja::proto::Type>(payload, n); \
    break;
    JA_PROTO_FOR_EACH_MESSAGE(JA_FUZZ_CASE)
#undef JA_FUZZ_CASE
    default:
      break;
  }
}

void feed(FrameDecoder& dec, const uint8_t* data, size_t size) {
  for (size_t i = 0; i < size; ++i) {
    if (dec.push(data[i]) == DecodeEvent::kFrame) {
      if (dec.payload_size() > ja::proto::kMaxPayload) abort();
      check_payload(dec.header().msg_id, dec.payload(), dec.payload_size());
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  FrameDecoder dec;
  feed(dec, data, size);
  const ja::proto::DecoderStats& st = dec.stats();
  if (st.bytes_skipped > size) abort();
  if (st.frames * (ja::proto::kMinBody + 2) > size + 1) abort();

  if (size >= 1) {
    const size_t n = size - 1 > ja::proto::kMaxPayload ? ja::proto::kMaxPayload : size - 1;
    const ja::proto::FrameHeader h = {ja::proto::kProtocolVersion, data[0], 7, 12345};
    uint8_t frame[ja::proto::kMaxFrameBytes];
    const size_t len = ja::proto::encode_frame(h, data + 1, n, frame, sizeof frame);
    if (len != n + 12) abort();
    for (size_t i = 0; i + 1 < len; ++i) {
      if (frame[i] == 0) abort();
    }
    const uint8_t zero = 0;
    feed(dec, &zero, 1);  // end whatever the garbage left open
    const uint32_t before = dec.stats().frames;
    int got = 0;
    for (size_t i = 0; i < len; ++i) {
      if (dec.push(frame[i]) == DecodeEvent::kFrame) {
        ++got;
        if (dec.header().msg_id != data[0] || dec.header().seq != 7 || dec.header().t_us != 12345 ||
            dec.payload_size() != n || (n > 0 && memcmp(dec.payload(), data + 1, n) != 0)) {
          abort();
        }
        check_payload(dec.header().msg_id, dec.payload(), dec.payload_size());
      }
    }
    if (got != 1 || dec.stats().frames != before + 1) abort();
  }
  return 0;
}
