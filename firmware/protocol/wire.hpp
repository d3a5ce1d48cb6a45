// Little-endian field access for the wire protocol (hand-written; used by the generated
// messages.hpp). Explicit byte shuffling instead of packed structs: identical on AVR and x86
// whatever the compiler's layout and alignment rules. C++11, no allocation.
#ifndef JA_PROTOCOL_WIRE_HPP_
#define JA_PROTOCOL_WIRE_HPP_

#include <stddef.h>
#include <stdint.h>
#include <string.h>

namespace ja {
namespace proto {

// Variable-length text that fills the rest of a payload (e.g. log lines). Not NUL-terminated.
template <size_t N>
struct Text {
  uint8_t len;  // bytes in use, <= N
  char data[N];
};

inline void put_u8(uint8_t* p, uint8_t v) { p[0] = v; }
inline void put_i8(uint8_t* p, int8_t v) { p[0] = static_cast<uint8_t>(v); }
inline void put_u16(uint8_t* p, uint16_t v) {
  p[0] = static_cast<uint8_t>(v);
  p[1] = static_cast<uint8_t>(v >> 8);
}
inline void put_i16(uint8_t* p, int16_t v) { put_u16(p, static_cast<uint16_t>(v)); }
inline void put_u32(uint8_t* p, uint32_t v) {
  p[0] = static_cast<uint8_t>(v);
  p[1] = static_cast<uint8_t>(v >> 8);
  p[2] = static_cast<uint8_t>(v >> 16);
  p[3] = static_cast<uint8_t>(v >> 24);
}
inline void put_i32(uint8_t* p, int32_t v) { put_u32(p, static_cast<uint32_t>(v)); }
// 24-bit two's complement; bits above 23 are dropped (the caller keeps values in range).
inline void put_i24(uint8_t* p, int32_t v) {
  const uint32_t u = static_cast<uint32_t>(v);
  p[0] = static_cast<uint8_t>(u);
  p[1] = static_cast<uint8_t>(u >> 8);
  p[2] = static_cast<uint8_t>(u >> 16);
}
inline void put_f32(uint8_t* p, float v) {
  uint32_t u;
  memcpy(&u, &v, sizeof u);
  put_u32(p, u);
}
inline void put_chars(uint8_t* p, const char* s, size_t n) { memcpy(p, s, n); }
template <size_t N>
void put_text(uint8_t* p, const Text<N>& t) {
  memcpy(p, t.data, t.len);
}

inline uint8_t get_u8(const uint8_t* p) { return p[0]; }
inline int8_t get_i8(const uint8_t* p) { return static_cast<int8_t>(p[0]); }
inline uint16_t get_u16(const uint8_t* p) {
  return static_cast<uint16_t>(p[0] | (static_cast<uint16_t>(p[1]) << 8));
}
inline int16_t get_i16(const uint8_t* p) { return static_cast<int16_t>(get_u16(p)); }
inline uint32_t get_u32(const uint8_t* p) {
  return static_cast<uint32_t>(p[0]) | (static_cast<uint32_t>(p[1]) << 8) |
         (static_cast<uint32_t>(p[2]) << 16) | (static_cast<uint32_t>(p[3]) << 24);
}
inline int32_t get_i32(const uint8_t* p) { return static_cast<int32_t>(get_u32(p)); }
inline int32_t get_i24(const uint8_t* p) {
  const uint32_t u = static_cast<uint32_t>(p[0]) | (static_cast<uint32_t>(p[1]) << 8) |
                     (static_cast<uint32_t>(p[2]) << 16);
  // Sign-extend bit 23 without relying on implementation-defined shifts of negatives.
  return static_cast<int32_t>(u ^ 0x800000u) - static_cast<int32_t>(0x800000);
}
inline float get_f32(const uint8_t* p) {
  const uint32_t u = get_u32(p);
  float v;
  memcpy(&v, &u, sizeof v);
  return v;
}
inline void get_chars(const uint8_t* p, char* s, size_t n) { memcpy(s, p, n); }
template <size_t N>
void get_text(const uint8_t* p, size_t n, Text<N>* t) {
  t->len = static_cast<uint8_t>(n);
  memcpy(t->data, p, n);
}

}  // namespace proto
}  // namespace ja

#endif  // JA_PROTOCOL_WIRE_HPP_
