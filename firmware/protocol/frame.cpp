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
// The encoder's CRC on the AVR: a 256-entry table in flash (512 B of program memory, no RAM),
//   crc' = (crc << 8) ^ T[(crc >> 8) ^ byte],  T[i] = 8 steps of the 0x1021 polynomial on i << 8,
// two LPMs (~12 cycles a byte) instead of ~22 for crc16_update's shifts. Same values (protocol/
// generate.py's vectors are checked on x86, the image's frames by the AVR image tests; the table
// was generated from that recurrence and checked against binascii.crc_hqx).
const uint16_t kCrcTable[256] PROGMEM = {
    0x0000, 0x1021, 0x2042, 0x3063, 0x4084, 0x50A5, 0x60C6, 0x70E7, 0x8108, 0x9129, 0xA14A, 0xB16B,
    0xC18C, 0xD1AD, 0xE1CE, 0xF1EF, 0x1231, 0x0210, 0x3273, 0x2252, 0x52B5, 0x4294, 0x72F7, 0x62D6,
    0x9339, 0x8318, 0xB37B, 0xA35A, 0xD3BD, 0xC39C, 0xF3FF, 0xE3DE, 0x2462, 0x3443, 0x0420, 0x1401,
    0x64E6, 0x74C7, 0x44A4, 0x5485, 0xA56A, 0xB54B, 0x8528, 0x9509, 0xE5EE, 0xF5CF, 0xC5AC, 0xD58D,
    0x3653, 0x2672, 0x1611, 0x0630, 0x76D7, 0x66F6, 0x5695, 0x46B4, 0xB75B, 0xA77A, 0x9719, 0x8738,
    0xF7DF, 0xE7FE, 0xD79D, 0xC7BC, 0x48C4, 0x58E5, 0x6886, 0x78A7, 0x0840, 0x1861, 0x2802, 0x3823,
    0xC9CC, 0xD9ED, 0xE98E, 0xF9AF, 0x8948, 0x9969, 0xA90A, 0xB92B, 0x5AF5, 0x4AD4, 0x7AB7, 0x6A96,
    0x1A71, 0x0A50, 0x3A33, 0x2A12, 0xDBFD, 0xCBDC, 0xFBBF, 0xEB9E, 0x9B79, 0x8B58, 0xBB3B, 0xAB1A,
    0x6CA6, 0x7C87, 0x4CE4, 0x5CC5, 0x2C22, 0x3C03, 0x0C60, 0x1C41, 0xEDAE, 0xFD8F, 0xCDEC, 0xDDCD,
    0xAD2A, 0xBD0B, 0x8D68, 0x9D49, 0x7E97, 0x6EB6, 0x5ED5, 0x4EF4, 0x3E13, 0x2E32, 0x1E51, 0x0E70,
    0xFF9F, 0xEFBE, 0xDFDD, 0xCFFC, 0xBF1B, 0xAF3A, 0x9F59, 0x8F78, 0x9188, 0x81A9, 0xB1CA, 0xA1EB,
    0xD10C, 0xC12D, 0xF14E, 0xE16F, 0x1080, 0x00A1, 0x30C2, 0x20E3, 0x5004, 0x4025, 0x7046, 0x6067,
    0x83B9, 0x9398, 0xA3FB, 0xB3DA, 0xC33D, 0xD31C, 0xE37F, 0xF35E, 0x02B1, 0x1290, 0x22F3, 0x32D2,
    0x4235, 0x5214, 0x6277, 0x7256, 0xB5EA, 0xA5CB, 0x95A8, 0x8589, 0xF56E, 0xE54F, 0xD52C, 0xC50D,
    0x34E2, 0x24C3, 0x14A0, 0x0481, 0x7466, 0x6447, 0x5424, 0x4405, 0xA7DB, 0xB7FA, 0x8799, 0x97B8,
    0xE75F, 0xF77E, 0xC71D, 0xD73C, 0x26D3, 0x36F2, 0x0691, 0x16B0, 0x6657, 0x7676, 0x4615, 0x5634,
    0xD94C, 0xC96D, 0xF90E, 0xE92F, 0x99C8, 0x89E9, 0xB98A, 0xA9AB, 0x5844, 0x4865, 0x7806, 0x6827,
    0x18C0, 0x08E1, 0x3882, 0x28A3, 0xCB7D, 0xDB5C, 0xEB3F, 0xFB1E, 0x8BF9, 0x9BD8, 0xABBB, 0xBB9A,
    0x4A75, 0x5A54, 0x6A37, 0x7A16, 0x0AF1, 0x1AD0, 0x2AB3, 0x3A92, 0xFD2E, 0xED0F, 0xDD6C, 0xCD4D,
    0xBDAA, 0xAD8B, 0x9DE8, 0x8DC9, 0x7C26, 0x6C07, 0x5C64, 0x4C45, 0x3CA2, 0x2C83, 0x1CE0, 0x0CC1,
    0xEF1F, 0xFF3E, 0xCF5D, 0xDF7C, 0xAF9B, 0xBFBA, 0x8FD9, 0x9FF8, 0x6E17, 0x7E36, 0x4E55, 0x5E74,
    0x2E93, 0x3EB2, 0x0ED1, 0x1EF0,
};

inline uint16_t CrcStep(uint16_t crc, uint8_t byte) {
  const uint8_t i = static_cast<uint8_t>(static_cast<uint8_t>(crc >> 8) ^ byte);
  return static_cast<uint16_t>((crc << 8) ^ pgm_read_word(&kCrcTable[i]));
}
#else
inline uint16_t CrcStep(uint16_t crc, uint8_t byte) { return crc16_update(crc, byte); }
#endif

}  // namespace

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
    crc = CrcStep(crc, v);
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
