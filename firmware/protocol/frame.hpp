// Framing of the jointangle wire protocol (hand-written; the Python twin is
// host/jointangle/protocol/framing.py, and both are checked against protocol/vectors/).
//
//   body  = version:u8 | msg_id:u8 | seq:u16 | t_us:u32 | payload (<= kMaxPayload) | crc:u16
//   wire  = COBS(body XOR 0x55 byte-wise) | 0x00
//
// Little-endian throughout; crc = CRC-16/CCITT-FALSE over everything before it (unwhitened).
// Whitening: small integers are full of 0x00/0xFF bytes, and every 0x00 would become a COBS code
// byte; XOR with 0x55 first makes code bytes rare (a frame has ~1 instead of ~20), which is what
// lets the host's vectorised decoder walk all code chains in a few numpy steps. A body is at most
// 250 bytes, so COBS always adds exactly one byte (no 254-byte blocks). No allocation: the
// decoder owns one kMaxBody buffer and takes one byte at a time (call it from the UART RX path).
#ifndef JA_PROTOCOL_FRAME_HPP_
#define JA_PROTOCOL_FRAME_HPP_

#include <stddef.h>
#include <stdint.h>

#include "protocol/messages.hpp"

namespace ja {
namespace proto {

constexpr size_t kHeaderSize = 8;
constexpr uint8_t kWhiten = 0x55;  // XORed into every body byte before COBS
constexpr size_t kCrcSize = 2;
constexpr size_t kMinBody = kHeaderSize + kCrcSize;
constexpr size_t kMaxBody = kHeaderSize + kMaxPayload + kCrcSize;  // 250
constexpr size_t kMaxEncoded = kMaxBody + 1;        // longest valid chunk between delimiters
constexpr size_t kMaxFrameBytes = kMaxEncoded + 1;  // + the 0x00 delimiter
// Where encode_* expects the payload inside the output buffer (COBS code byte + header).
constexpr size_t kPayloadOffset = 1 + kHeaderSize;

struct FrameHeader {
  uint8_t version;
  uint8_t msg_id;
  uint16_t seq;   // per-sender frame counter, wraps
  uint32_t t_us;  // sender's clock in microseconds, wraps (~71.6 min)
};

// Frames a payload that the caller has already written at out + kPayloadOffset: writes the header
// and CRC, COBS-encodes in place and appends the delimiter. Returns the bytes to send, or 0 if the
// payload is longer than kMaxPayload or `cap` is smaller than payload_len + 12.
size_t finish_frame(const FrameHeader& header, size_t payload_len, uint8_t* out, size_t cap);

// Bytes finish_frame produces for a payload of payload_len bytes (0 when it is too long).
constexpr size_t framed_size(size_t payload_len) {
  return payload_len > kMaxPayload ? 0 : kHeaderSize + payload_len + kCrcSize + 2;
}

#if defined(__AVR__)
// finish_frame's bytes written into a 256-byte ring buffer (256-aligned) from index `head` on,
// wrapping at its end, instead of in place: `frame` holds the payload at kPayloadOffset (its
// header bytes are overwritten, the rest is only read). Returns framed_size(payload_len); the
// caller checked that the ring has that much room. Saves the copy of the encoded frame into a
// transmit ring (the AVR board's Usart0::TxFrame).
size_t finish_frame_to_ring(const FrameHeader& header, size_t payload_len, uint8_t* frame,
                            uint8_t* ring, uint8_t head);
#endif

// Copies `payload` into `out` and frames it (see finish_frame). `payload` must not overlap `out`.
size_t encode_frame(const FrameHeader& header, const uint8_t* payload, size_t payload_len,
                    uint8_t* out, size_t cap);

// Encodes a generated message struct as one frame; no buffer besides `out`. 0 on failure.
template <class Msg>
size_t encode_message(const Msg& msg, uint16_t seq, uint32_t t_us, uint8_t* out, size_t cap) {
  if (cap < kPayloadOffset + kCrcSize + 1) return 0;
  size_t room = cap - kPayloadOffset - kCrcSize - 1;
  if (room > kMaxPayload) room = kMaxPayload;
  size_t len = 0;
  if (!msg.encode(out + kPayloadOffset, room, &len)) return 0;
  const FrameHeader header = {kProtocolVersion, Msg::kId, seq, t_us};
  return finish_frame(header, len, out, cap);
}

// Damage and traffic counters. bytes_skipped counts the bytes of every rejected chunk (the
// delimiters themselves are never counted); frames_lost is the sum of sequence gaps between
// accepted frames (a hello with seq 0 marks a device restart and is not a gap).
struct DecoderStats {
  uint32_t frames;          // accepted frames
  uint32_t crc_errors;      // well-formed COBS, wrong CRC
  uint32_t malformed;       // invalid COBS or shorter than header + CRC
  uint32_t oversize;        // chunks longer than kMaxEncoded
  uint32_t version_errors;  // good CRC, other protocol version: refused
  uint32_t frames_lost;     // sequence gaps
  uint32_t bytes_skipped;   // bytes of rejected chunks
};

enum class DecodeEvent : uint8_t {
  kNone,      // byte consumed, nothing completed
  kFrame,     // a frame is ready: header(), payload(), payload_size()
  kCrcError,  // a chunk was rejected (see DecoderStats for the meaning of each)
  kMalformed,
  kOversize,
  kVersionMismatch,  // mismatched_version() names the sender's version
};

// Byte-at-a-time decoder: resynchronises at every 0x00, never reads or writes out of bounds.
class FrameDecoder {
 public:
  FrameDecoder() { reset(); }

  DecodeEvent push(uint8_t byte);
  // Clears the partial chunk and the counters.
  void reset();

  const FrameHeader& header() const { return header_; }
  const uint8_t* payload() const { return buf_ + kHeaderSize; }
  size_t payload_size() const { return payload_size_; }
  const DecoderStats& stats() const { return stats_; }
  uint8_t mismatched_version() const { return mismatched_version_; }

 private:
  DecodeEvent end_chunk();
  void start_chunk();

  uint8_t buf_[kMaxBody];
  FrameHeader header_;
  DecoderStats stats_;
  uint32_t raw_len_;  // encoded bytes in the current chunk (saturates)
  size_t len_;        // decoded bytes stored in buf_
  size_t payload_size_;
  uint8_t code_;  // current COBS code byte
  uint8_t left_;  // data bytes left in the current COBS block; 0 = expect a code byte
  uint8_t mismatched_version_;
  bool have_seq_;
  uint16_t last_seq_;
};

}  // namespace proto
}  // namespace ja

#endif  // JA_PROTOCOL_FRAME_HPP_
