// Framing: see frame.hpp. Written for C++11 (avr-gcc 5.4) and x86 alike.
#include "protocol/frame.hpp"

#include <string.h>
#if defined(__AVR__)
#include <avr/pgmspace.h>
#endif

#include "protocol/crc16.hpp"
#include "protocol/wire.hpp"

namespace ja {
namespace proto {

namespace {

#if defined(__AVR__)
// The encoder's CRC on the AVR from a 256-entry table in flash (512 B of program memory, no RAM):
//   crc' = (crc << 8) ^ T[(crc >> 8) ^ byte],  T[i] = 8 steps of the 0x1021 polynomial on i << 8,
// i.e. hi' = lo ^ T_hi[i], lo' = T_lo[i]: the high and low bytes of T are two 256-byte tables
// aligned to 256, so the index is the low byte of the flash address (one LPM each). Generated
// from that recurrence and checked against binascii.crc_hqx; the AVR image tests decode the
// image's frames (CRC checked) and protocol_vectors checks the portable path on x86.
const uint8_t kCrcHi[256] PROGMEM __attribute__((aligned(256))) = {
    0x00, 0x10, 0x20, 0x30, 0x40, 0x50, 0x60, 0x70, 0x81, 0x91, 0xA1, 0xB1, 0xC1, 0xD1, 0xE1, 0xF1,
    0x12, 0x02, 0x32, 0x22, 0x52, 0x42, 0x72, 0x62, 0x93, 0x83, 0xB3, 0xA3, 0xD3, 0xC3, 0xF3, 0xE3,
    0x24, 0x34, 0x04, 0x14, 0x64, 0x74, 0x44, 0x54, 0xA5, 0xB5, 0x85, 0x95, 0xE5, 0xF5, 0xC5, 0xD5,
    0x36, 0x26, 0x16, 0x06, 0x76, 0x66, 0x56, 0x46, 0xB7, 0xA7, 0x97, 0x87, 0xF7, 0xE7, 0xD7, 0xC7,
    0x48, 0x58, 0x68, 0x78, 0x08, 0x18, 0x28, 0x38, 0xC9, 0xD9, 0xE9, 0xF9, 0x89, 0x99, 0xA9, 0xB9,
    0x5A, 0x4A, 0x7A, 0x6A, 0x1A, 0x0A, 0x3A, 0x2A, 0xDB, 0xCB, 0xFB, 0xEB, 0x9B, 0x8B, 0xBB, 0xAB,
    0x6C, 0x7C, 0x4C, 0x5C, 0x2C, 0x3C, 0x0C, 0x1C, 0xED, 0xFD, 0xCD, 0xDD, 0xAD, 0xBD, 0x8D, 0x9D,
    0x7E, 0x6E, 0x5E, 0x4E, 0x3E, 0x2E, 0x1E, 0x0E, 0xFF, 0xEF, 0xDF, 0xCF, 0xBF, 0xAF, 0x9F, 0x8F,
    0x91, 0x81, 0xB1, 0xA1, 0xD1, 0xC1, 0xF1, 0xE1, 0x10, 0x00, 0x30, 0x20, 0x50, 0x40, 0x70, 0x60,
    0x83, 0x93, 0xA3, 0xB3, 0xC3, 0xD3, 0xE3, 0xF3, 0x02, 0x12, 0x22, 0x32, 0x42, 0x52, 0x62, 0x72,
    0xB5, 0xA5, 0x95, 0x85, 0xF5, 0xE5, 0xD5, 0xC5, 0x34, 0x24, 0x14, 0x04, 0x74, 0x64, 0x54, 0x44,
    0xA7, 0xB7, 0x87, 0x97, 0xE7, 0xF7, 0xC7, 0xD7, 0x26, 0x36, 0x06, 0x16, 0x66, 0x76, 0x46, 0x56,
    0xD9, 0xC9, 0xF9, 0xE9, 0x99, 0x89, 0xB9, 0xA9, 0x58, 0x48, 0x78, 0x68, 0x18, 0x08, 0x38, 0x28,
    0xCB, 0xDB, 0xEB, 0xFB, 0x8B, 0x9B, 0xAB, 0xBB, 0x4A, 0x5A, 0x6A, 0x7A, 0x0A, 0x1A, 0x2A, 0x3A,
    0xFD, 0xED, 0xDD, 0xCD, 0xBD, 0xAD, 0x9D, 0x8D, 0x7C, 0x6C, 0x5C, 0x4C, 0x3C, 0x2C, 0x1C, 0x0C,
    0xEF, 0xFF, 0xCF, 0xDF, 0xAF, 0xBF, 0x8F, 0x9F, 0x6E, 0x7E, 0x4E, 0x5E, 0x2E, 0x3E, 0x0E, 0x1E,
};
const uint8_t kCrcLo[256] PROGMEM __attribute__((aligned(256))) = {
    0x00, 0x21, 0x42, 0x63, 0x84, 0xA5, 0xC6, 0xE7, 0x08, 0x29, 0x4A, 0x6B, 0x8C, 0xAD, 0xCE, 0xEF,
    0x31, 0x10, 0x73, 0x52, 0xB5, 0x94, 0xF7, 0xD6, 0x39, 0x18, 0x7B, 0x5A, 0xBD, 0x9C, 0xFF, 0xDE,
    0x62, 0x43, 0x20, 0x01, 0xE6, 0xC7, 0xA4, 0x85, 0x6A, 0x4B, 0x28, 0x09, 0xEE, 0xCF, 0xAC, 0x8D,
    0x53, 0x72, 0x11, 0x30, 0xD7, 0xF6, 0x95, 0xB4, 0x5B, 0x7A, 0x19, 0x38, 0xDF, 0xFE, 0x9D, 0xBC,
    0xC4, 0xE5, 0x86, 0xA7, 0x40, 0x61, 0x02, 0x23, 0xCC, 0xED, 0x8E, 0xAF, 0x48, 0x69, 0x0A, 0x2B,
    0xF5, 0xD4, 0xB7, 0x96, 0x71, 0x50, 0x33, 0x12, 0xFD, 0xDC, 0xBF, 0x9E, 0x79, 0x58, 0x3B, 0x1A,
    0xA6, 0x87, 0xE4, 0xC5, 0x22, 0x03, 0x60, 0x41, 0xAE, 0x8F, 0xEC, 0xCD, 0x2A, 0x0B, 0x68, 0x49,
    0x97, 0xB6, 0xD5, 0xF4, 0x13, 0x32, 0x51, 0x70, 0x9F, 0xBE, 0xDD, 0xFC, 0x1B, 0x3A, 0x59, 0x78,
    0x88, 0xA9, 0xCA, 0xEB, 0x0C, 0x2D, 0x4E, 0x6F, 0x80, 0xA1, 0xC2, 0xE3, 0x04, 0x25, 0x46, 0x67,
    0xB9, 0x98, 0xFB, 0xDA, 0x3D, 0x1C, 0x7F, 0x5E, 0xB1, 0x90, 0xF3, 0xD2, 0x35, 0x14, 0x77, 0x56,
    0xEA, 0xCB, 0xA8, 0x89, 0x6E, 0x4F, 0x2C, 0x0D, 0xE2, 0xC3, 0xA0, 0x81, 0x66, 0x47, 0x24, 0x05,
    0xDB, 0xFA, 0x99, 0xB8, 0x5F, 0x7E, 0x1D, 0x3C, 0xD3, 0xF2, 0x91, 0xB0, 0x57, 0x76, 0x15, 0x34,
    0x4C, 0x6D, 0x0E, 0x2F, 0xC8, 0xE9, 0x8A, 0xAB, 0x44, 0x65, 0x06, 0x27, 0xC0, 0xE1, 0x82, 0xA3,
    0x7D, 0x5C, 0x3F, 0x1E, 0xF9, 0xD8, 0xBB, 0x9A, 0x75, 0x54, 0x37, 0x16, 0xF1, 0xD0, 0xB3, 0x92,
    0x2E, 0x0F, 0x6C, 0x4D, 0xAA, 0x8B, 0xE8, 0xC9, 0x26, 0x07, 0x64, 0x45, 0xA2, 0x83, 0xE0, 0xC1,
    0x1F, 0x3E, 0x5D, 0x7C, 0x9B, 0xBA, 0xD9, 0xF8, 0x17, 0x36, 0x55, 0x74, 0x93, 0xB2, 0xD1, 0xF0,
};

// CRC, whitening and COBS of the bytes [p, end) in place (see finish_frame), ~23 cycles a byte
// (the C loop compiled to ~31). X walks the bytes, Z indexes the tables and stores a code byte.
inline void EncodeRun(uint8_t*& p, uint8_t* end, uint8_t*& code, uint8_t& crc_hi, uint8_t& crc_lo) {
  uint8_t v, t;
  asm volatile(
      "1:                        \n\t"
      "cp   %A[p], %A[end]       \n\t"
      "cpc  %B[p], %B[end]       \n\t"
      "breq 3f                   \n\t"
      "ld   %[v], %a[p]          \n\t"
      "mov  r30, %[v]            \n\t"  // i = (crc >> 8) ^ byte
      "eor  r30, %[hi]           \n\t"
      "ldi  r31, hi8(%[th])      \n\t"
      "lpm  %[t], Z              \n\t"
      "eor  %[t], %[lo]          \n\t"  // hi' = lo ^ T_hi[i]
      "ldi  r31, hi8(%[tl])      \n\t"
      "lpm  %[lo], Z             \n\t"  // lo' = T_lo[i]
      "mov  %[hi], %[t]          \n\t"
      "eor  %[v], %[w]           \n\t"  // whiten
      "brne 2f                   \n\t"
      "mov  %[t], %A[p]          \n\t"  // a zero: *code = p - code, code = p
      "sub  %[t], %A[code]       \n\t"
      "movw r30, %[code]         \n\t"
      "st   Z, %[t]              \n\t"
      "movw %[code], %[p]        \n\t"
      "adiw %A[p], 1             \n\t"
      "rjmp 1b                   \n\t"
      "2:                        \n\t"
      "st   %a[p]+, %[v]         \n\t"
      "rjmp 1b                   \n\t"
      "3:                        \n\t"
      : [p] "+x"(p), [code] "+r"(code), [hi] "+r"(crc_hi), [lo] "+r"(crc_lo), [v] "=&r"(v),
        [t] "=&r"(t)
      : [end] "r"(end), [w] "r"(kWhiten), [th] "i"(kCrcHi), [tl] "i"(kCrcLo)
      : "r30", "r31", "memory");
}

/// EncodeRun with the output in a 256-aligned ring (high address byte `ring_hi`) at index d,
/// wrapping: reads `count` (>= 1) bytes from p, writes ring[d++]; a zero after whitening closes the
/// COBS block whose code byte is at ring[code] (ring[code] = d - code, mod 256: blocks are < 256
/// bytes). ~26 cycles a byte (the in-place loop ~23, plus the copy into the ring it saves: ~8).
inline void EncodeRunToRing(const uint8_t*& p, uint8_t count, uint8_t ring_hi, uint8_t& d,
                            uint8_t& code, uint8_t& crc_hi, uint8_t& crc_lo) {
  uint8_t v, t;
  asm volatile(
      "1:                        \n\t"
      "ld   %[v], %a[p]+         \n\t"
      "mov  r30, %[v]            \n\t"  // i = (crc >> 8) ^ byte
      "eor  r30, %[hi]           \n\t"
      "ldi  r31, hi8(%[th])      \n\t"
      "lpm  %[t], Z              \n\t"
      "eor  %[t], %[lo]          \n\t"  // hi' = lo ^ T_hi[i]
      "ldi  r31, hi8(%[tl])      \n\t"
      "lpm  %[lo], Z             \n\t"  // lo' = T_lo[i]
      "mov  %[hi], %[t]          \n\t"
      "eor  %[v], %[w]           \n\t"  // whiten
      "brne 2f                   \n\t"
      "mov  %[t], %[d]           \n\t"  // a zero: ring[code] = d - code, code = d
      "sub  %[t], %[code]        \n\t"
      "mov  r30, %[code]         \n\t"
      "mov  r31, %[rh]           \n\t"
      "st   Z, %[t]              \n\t"
      "mov  %[code], %[d]        \n\t"
      "rjmp 3f                   \n\t"
      "2:                        \n\t"
      "mov  r30, %[d]            \n\t"  // ring[d] = v
      "mov  r31, %[rh]           \n\t"
      "st   Z, %[v]              \n\t"
      "3:                        \n\t"
      "inc  %[d]                 \n\t"
      "dec  %[n]                 \n\t"
      "brne 1b                   \n\t"
      : [p] "+x"(p), [d] "+r"(d), [code] "+r"(code), [hi] "+r"(crc_hi), [lo] "+r"(crc_lo),
        [n] "+r"(count), [v] "=&r"(v), [t] "=&r"(t)
      : [w] "r"(kWhiten), [rh] "r"(ring_hi), [th] "i"(kCrcHi), [tl] "i"(kCrcLo)
      : "r30", "r31", "memory");
}
#endif

}  // namespace

#if defined(__AVR__)
size_t finish_frame_to_ring(const FrameHeader& header, size_t payload_len, uint8_t* frame,
                            uint8_t* ring, uint8_t head) {
  const size_t n = framed_size(payload_len);
  if (n == 0) return 0;
  uint8_t* b = frame + 1;  // as finish_frame: header, payload, CRC form the body at out + 1
  put_u8(b + 0, header.version);
  put_u8(b + 1, header.msg_id);
  put_u16(b + 2, header.seq);
  put_u32(b + 4, header.t_us);
  // Ring index i stands for finish_frame's out + (i - head): its code byte first, then the body.
  uint8_t code = head;
  uint8_t d = static_cast<uint8_t>(head + 1);
  const uint8_t* p = b;
  uint8_t crc_hi = static_cast<uint8_t>(kCrcInit >> 8), crc_lo = static_cast<uint8_t>(kCrcInit);
  // count = header + payload bytes: 8..247, never 0 (the loop runs at least once).
  EncodeRunToRing(p, static_cast<uint8_t>(kHeaderSize + payload_len),
                  static_cast<uint8_t>(reinterpret_cast<uintptr_t>(ring) >> 8), d, code, crc_hi,
                  crc_lo);
  const uint8_t tail[kCrcSize] = {crc_lo, crc_hi};
  for (size_t i = 0; i < kCrcSize; ++i, ++d) {
    const uint8_t w = static_cast<uint8_t>(tail[i] ^ kWhiten);
    if (w == 0) {
      ring[code] = static_cast<uint8_t>(d - code);
      code = d;
    } else {
      ring[d] = w;
    }
  }
  ring[code] = static_cast<uint8_t>(d - code);
  ring[d] = 0;
  return n;
}
#endif

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
  uint8_t* code = out;
  uint8_t* p = b;
  uint8_t* const crc_at = b + kHeaderSize + payload_len;
#if defined(__AVR__)
  uint8_t crc_hi = static_cast<uint8_t>(kCrcInit >> 8), crc_lo = static_cast<uint8_t>(kCrcInit);
  EncodeRun(p, crc_at, code, crc_hi, crc_lo);
  const uint16_t crc = static_cast<uint16_t>((static_cast<uint16_t>(crc_hi) << 8) | crc_lo);
#else
  uint16_t crc = kCrcInit;
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
#endif
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
