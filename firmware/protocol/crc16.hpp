// CRC-16/CCITT-FALSE: polynomial 0x1021, init 0xFFFF, no reflection, no final XOR.
// Check value: crc16("123456789") == 0x29B1. Table-free (no 512-byte table in the MCU's RAM);
// the Python twin is binascii.crc_hqx(data, 0xFFFF) (host/jointangle/protocol/framing.py).
#ifndef JA_PROTOCOL_CRC16_HPP_
#define JA_PROTOCOL_CRC16_HPP_

#include <stddef.h>
#include <stdint.h>

namespace ja {
namespace proto {

constexpr uint16_t kCrcInit = 0xFFFF;

// Feeds one byte (the shift-free byte-wise form of the 0x1021 polynomial):
//   x = (crc >> 8) ^ byte;  x ^= x >> 4;  crc' = (crc << 8) ^ (x << 12) ^ (x << 5) ^ x.
// Written on the two bytes separately, so an 8-bit MCU does only 8-bit shifts (AVR: ~20 cycles
// a byte instead of ~40 for the 16-bit shifts):
//   hi' = lo ^ (x << 4) ^ (x >> 3)   [(x << 12) and (x << 5) land x's bits 0-3 and 3-7 here]
//   lo' = (x << 5) ^ x               [the low byte of (x << 5), and x itself]
inline uint16_t crc16_update(uint16_t crc, uint8_t byte) {
  uint8_t x = static_cast<uint8_t>(static_cast<uint8_t>(crc >> 8) ^ byte);
  x = static_cast<uint8_t>(x ^ (x >> 4));
  const uint8_t hi = static_cast<uint8_t>(static_cast<uint8_t>(crc) ^ static_cast<uint8_t>(x << 4) ^
                                          static_cast<uint8_t>(x >> 3));
  const uint8_t lo = static_cast<uint8_t>(static_cast<uint8_t>(x << 5) ^ x);
  return static_cast<uint16_t>((static_cast<uint16_t>(hi) << 8) | lo);
}

inline uint16_t crc16(const uint8_t* data, size_t n, uint16_t crc = kCrcInit) {
  for (size_t i = 0; i < n; ++i) crc = crc16_update(crc, data[i]);
  return crc;
}

}  // namespace proto
}  // namespace ja

#endif  // JA_PROTOCOL_CRC16_HPP_
