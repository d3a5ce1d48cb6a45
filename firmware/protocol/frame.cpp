// Framing: see frame.hpp. Written for C++11 (avr-gcc 5.4) and x86 alike.
#include "protocol/frame.hpp"

#include <string.h>

#include "protocol/crc16.hpp"
#include "protocol/wire.hpp"

namespace ja {
namespace proto {

size_t finish_frame(const FrameHeader& header, size_t payload_len, uint8_t* out, size_t cap) {
  if (payload_len > kMaxPayload) return 0;
  const size_t body = kHeaderSize + payload_len + kCrcSize;
  if (cap < body + 2) return 0;
  uint8_t* b = out + 1;  // the body sits one byte in: COBS turns its zeros into codes in place
  put_u8(b + 0, header.version);
  put_u8(b + 1, header.msg_id);
  put_u16(b + 2, header.seq);
  put_u32(b + 4, header.t_us);
  // One pass over the body for the CRC (of the unwhitened byte), the whitening and an in-place
  // COBS: out[0] plays the zero before the body; a byte whitening to zero becomes the code slot
  // of its block and the previous slot (`code`) receives the distance to it; the end receives
  // the last one. Blocks never reach 254 bytes because body <= 250.
  uint16_t crc = kCrcInit;
  uint8_t* code = out;
  uint8_t* p = b;
  uint8_t* const crc_at = b + kHeaderSize + payload_len;
  for (; p != crc_at; ++p) {
    const uint8_t v = *p;
    crc = crc16_update(crc, v);
    const uint8_t w = static_cast<uint8_t>(v ^ kWhiten);
    if (w == 0) {
      *code = static_cast<uint8_t>(p - code);
      code = p;
    } else {
      *p = w;
    }
  }
  const uint8_t tail[kCrcSize] = {static_cast<uint8_t>(crc), static_cast<uint8_t>(crc >> 8)};
  for (size_t i = 0; i < kCrcSize; ++i, ++p) {
    const uint8_t w = static_cast<uint8_t>(tail[i] ^ kWhiten);
    if (w == 0) {
      *code = static_cast<uint8_t>(p - code);
      code = p;
    } else {
      *p = w;
    }
  }
  *code = static_cast<uint8_t>(p - code);
  *p = 0;
  return body + 2;
}

size_t encode_frame(const FrameHeader& header, const uint8_t* payload, size_t payload_len,
                    uint8_t* out, size_t cap) {
  if (payload_len > kMaxPayload || cap < kPayloadOffset + payload_len + kCrcSize + 1) return 0;
  if (payload_len > 0) memcpy(out + kPayloadOffset, payload, payload_len);
  return finish_frame(header, payload_len, out, cap);
}

void FrameDecoder::reset() {
  memset(&stats_, 0, sizeof stats_);
  memset(&header_, 0, sizeof header_);
  payload_size_ = 0;
  mismatched_version_ = 0;
  have_seq_ = false;
  last_seq_ = 0;
  start_chunk();
}

void FrameDecoder::start_chunk() {
  raw_len_ = 0;
  len_ = 0;
  code_ = 0;
  left_ = 0;
}

DecodeEvent FrameDecoder::push(uint8_t byte) {
  if (byte == 0) return end_chunk();
  if (raw_len_ != UINT32_MAX) ++raw_len_;
  if (raw_len_ > kMaxEncoded) return DecodeEvent::kNone;  // oversize: count at the delimiter
  if (left_ == 0) {
    // A code byte: the previous block (if any, and shorter than 254) ended in a (whitened)
    // zero, i.e. an original byte equal to kWhiten.
    if (raw_len_ > 1 && code_ != 0xFF) buf_[len_++] = kWhiten;
    code_ = byte;
    left_ = static_cast<uint8_t>(byte - 1);
  } else {
    buf_[len_++] = static_cast<uint8_t>(byte ^ kWhiten);
    --left_;
  }
  return DecodeEvent::kNone;
}

DecodeEvent FrameDecoder::end_chunk() {
  const uint32_t n = raw_len_;
  const size_t len = len_;
  const bool cobs_ok = left_ == 0;
  start_chunk();
  if (n == 0) return DecodeEvent::kNone;  // back-to-back delimiters: nothing to count
  if (n > kMaxEncoded) {
    ++stats_.oversize;
    stats_.bytes_skipped += n;
    return DecodeEvent::kOversize;
  }
  if (!cobs_ok || len < kMinBody) {
    ++stats_.malformed;
    stats_.bytes_skipped += n;
    return DecodeEvent::kMalformed;
  }
  const size_t crc_at = len - kCrcSize;
  if (crc16(buf_, crc_at) != get_u16(buf_ + crc_at)) {
    ++stats_.crc_errors;
    stats_.bytes_skipped += n;
    return DecodeEvent::kCrcError;
  }
  if (buf_[0] != kProtocolVersion) {
    ++stats_.version_errors;
    stats_.bytes_skipped += n;
    mismatched_version_ = buf_[0];
    return DecodeEvent::kVersionMismatch;
  }
  header_.version = buf_[0];
  header_.msg_id = buf_[1];
  header_.seq = get_u16(buf_ + 2);
  header_.t_us = get_u32(buf_ + 4);
  payload_size_ = crc_at - kHeaderSize;
  const bool restart = header_.msg_id == Hello::kId && header_.seq == 0;
  if (have_seq_ && !restart) {
    stats_.frames_lost += static_cast<uint16_t>(header_.seq - last_seq_ - 1u);
  }
  have_seq_ = true;
  last_seq_ = header_.seq;
  ++stats_.frames;
  return DecodeEvent::kFrame;
}

}  // namespace proto
}  // namespace ja
