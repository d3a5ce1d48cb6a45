// Q-format fixed-point scalar for the firmware core, usable as an Eigen scalar.
//
// Fixed<F> stores a real value v as the int32 raw = round(v * 2^F) ("Q(31-F).F"). Arithmetic is
// saturating and never has undefined behaviour: results outside [-2^31, 2^31 - 1] raw clamp to the
// nearest end and increment the saturation counter (SaturationCount()). Products use 64 bits only
// as an intermediate. Rounding is round-half-up everywhere (floor(x + 1/2)), identical on AVR and
// x86, so the AVR image and the x86 build agree bit for bit.
//
// AVR cost notes (measured, see NUMERICS.md): a product needs the 64-bit intermediate, which
// avr-gcc builds with a generic 64x64 libcall (~260 cycles) plus a bit-by-bit shift loop. Here the
// 32x32->64 product is 16 hardware MULs in inline assembly and the >> F is a byte move when F is a
// multiple of 8, so F in {8, 16, 24} is the fast path.
#pragma once

#include <stdint.h>

#include "config.hpp"

// Force inlining of the arithmetic: on AVR a call plus a struct return through the stack costs more
// than the product itself (measured: 348 vs ~110 cycles).
#define JA_FORCE_INLINE inline __attribute__((always_inline))
// Keeps a kernel out of line (one copy, called): see numeric_policy.hpp.
#define JA_NOINLINE __attribute__((noinline))

namespace ja {
namespace core {

/// Saturation events since the last reset (wraps at 65535). One counter for the whole core:
/// operators of an Eigen scalar cannot carry context; the filter reads and resets it per step.
inline uint16_t& SaturationCount() {
  static uint16_t count = 0;
  return count;
}

namespace detail {

/// 64-bit product a * b as {lo, hi} words: a * b = hi * 2^32 + lo (hi signed).
struct Wide {
  uint32_t lo;
  int32_t hi;
};

JA_FORCE_INLINE Wide MultiplyWide(int32_t a, int32_t b) {
#if defined(__AVR__) && defined(__AVR_HAVE_MUL__)
  // Unsigned 32x32->64 by columns (schoolbook on bytes, 16 MULs), then the signed correction
  // a*b = ua*ub - 2^32 * ((a<0 ? ub : 0) + (b<0 ? ua : 0))  (mod 2^64).
  // Column order bounds every carry to two bytes above the product (checked exhaustively over
  // byte patterns and 2e5 random pairs when written).
  uint32_t lo;
  uint32_t hi;
  const uint8_t zero = 0;
  asm("\n\t"
      "clr %A0\n\t"
      "clr %B0\n\t"
      "clr %C0\n\t"
      "clr %D0\n\t"
      "clr %A1\n\t"
      "clr %B1\n\t"
      "clr %C1\n\t"
      "clr %D1\n\t"
      "mul %A2, %A3\n\t"
      "add %A0, r0\n\t"
      "adc %B0, r1\n\t"
      "adc %C0, %4\n\t"
      "mul %A2, %B3\n\t"
      "add %B0, r0\n\t"
      "adc %C0, r1\n\t"
      "adc %D0, %4\n\t"
      "mul %B2, %A3\n\t"
      "add %B0, r0\n\t"
      "adc %C0, r1\n\t"
      "adc %D0, %4\n\t"
      "mul %A2, %C3\n\t"
      "add %C0, r0\n\t"
      "adc %D0, r1\n\t"
      "adc %A1, %4\n\t"
      "mul %B2, %B3\n\t"
      "add %C0, r0\n\t"
      "adc %D0, r1\n\t"
      "adc %A1, %4\n\t"
      "mul %C2, %A3\n\t"
      "add %C0, r0\n\t"
      "adc %D0, r1\n\t"
      "adc %A1, %4\n\t"
      "mul %A2, %D3\n\t"
      "add %D0, r0\n\t"
      "adc %A1, r1\n\t"
      "adc %B1, %4\n\t"
      "mul %B2, %C3\n\t"
      "add %D0, r0\n\t"
      "adc %A1, r1\n\t"
      "adc %B1, %4\n\t"
      "mul %C2, %B3\n\t"
      "add %D0, r0\n\t"
      "adc %A1, r1\n\t"
      "adc %B1, %4\n\t"
      "mul %D2, %A3\n\t"
      "add %D0, r0\n\t"
      "adc %A1, r1\n\t"
      "adc %B1, %4\n\t"
      "mul %B2, %D3\n\t"
      "add %A1, r0\n\t"
      "adc %B1, r1\n\t"
      "adc %C1, %4\n\t"
      "mul %C2, %C3\n\t"
      "add %A1, r0\n\t"
      "adc %B1, r1\n\t"
      "adc %C1, %4\n\t"
      "mul %D2, %B3\n\t"
      "add %A1, r0\n\t"
      "adc %B1, r1\n\t"
      "adc %C1, %4\n\t"
      "mul %C2, %D3\n\t"
      "add %B1, r0\n\t"
      "adc %C1, r1\n\t"
      "adc %D1, %4\n\t"
      "mul %D2, %C3\n\t"
      "add %B1, r0\n\t"
      "adc %C1, r1\n\t"
      "adc %D1, %4\n\t"
      "mul %D2, %D3\n\t"
      "add %C1, r0\n\t"
      "adc %D1, r1\n\t"
      "clr __zero_reg__\n\t"
      // The signs in assembly (a skip over 4 subtractions; the C form's taken branch was a
      // jump out of line and back, 12 cycles instead of 6).
      "sbrs %D2, 7\n\t"
      "rjmp 1f\n\t"
      "sub %A1, %A3\n\t"
      "sbc %B1, %B3\n\t"
      "sbc %C1, %C3\n\t"
      "sbc %D1, %D3\n"
      "1:\n\t"
      "sbrs %D3, 7\n\t"
      "rjmp 2f\n\t"
      "sub %A1, %A2\n\t"
      "sbc %B1, %B2\n\t"
      "sbc %C1, %C2\n\t"
      "sbc %D1, %D2\n"
      "2:"
      : "=&r"(lo), "=&r"(hi)
      : "r"(a), "r"(b), "r"(zero)
      : "r0");
  return Wide{lo, static_cast<int32_t>(hi)};
#else
  const int64_t p = static_cast<int64_t>(a) * static_cast<int64_t>(b);
  const uint64_t u = static_cast<uint64_t>(p);
  return Wide{static_cast<uint32_t>(u), static_cast<int32_t>(static_cast<uint32_t>(u >> 32))};
#endif
}

/// 48-bit product a * b of a signed 32-bit and an unsigned 16-bit operand as {lo, hi} (hi
/// sign-extended). On AVR 8 MULs (half the 32x32 product): the three products that do not
/// overlap (a0 b0, a1 b1, a3 b1 at bytes 0, 2, 4) are moved into place, the other five added
/// with their carries rippled to byte 5 (the unsigned product is < 2^48), then
/// a*b = ua*b - 2^32 * (a < 0 ? b : 0).
JA_FORCE_INLINE Wide MultiplyWide32x16(int32_t a, uint16_t b) {
#if defined(__AVR__) && defined(__AVR_HAVE_MUL__)
  uint32_t lo;
  uint32_t hi;
  const uint8_t zero = 0;
  asm("\n\t"
      "mul %A[a], %A[b]\n\t"
      "movw %A[lo], r0\n\t"
      "mul %B[a], %B[b]\n\t"
      "movw %C[lo], r0\n\t"
      "mul %D[a], %B[b]\n\t"
      "movw %A[hi], r0\n\t"
      "clr %C[hi]\n\t"
      "clr %D[hi]\n\t"
      "mul %A[a], %B[b]\n\t"
      "add %B[lo], r0\n\t"
      "adc %C[lo], r1\n\t"
      "adc %D[lo], %[z]\n\t"
      "adc %A[hi], %[z]\n\t"
      "adc %B[hi], %[z]\n\t"
      "mul %B[a], %A[b]\n\t"
      "add %B[lo], r0\n\t"
      "adc %C[lo], r1\n\t"
      "adc %D[lo], %[z]\n\t"
      "adc %A[hi], %[z]\n\t"
      "adc %B[hi], %[z]\n\t"
      "mul %C[a], %A[b]\n\t"
      "add %C[lo], r0\n\t"
      "adc %D[lo], r1\n\t"
      "adc %A[hi], %[z]\n\t"
      "adc %B[hi], %[z]\n\t"
      "mul %C[a], %B[b]\n\t"
      "add %D[lo], r0\n\t"
      "adc %A[hi], r1\n\t"
      "adc %B[hi], %[z]\n\t"
      "mul %D[a], %A[b]\n\t"
      "add %D[lo], r0\n\t"
      "adc %A[hi], r1\n\t"
      "adc %B[hi], %[z]\n\t"
      "clr __zero_reg__\n\t"
      : [lo] "=&r"(lo), [hi] "=&r"(hi)
      : [a] "r"(a), [b] "r"(b), [z] "r"(zero)
      : "r0");
  if (a < 0) hi -= b;
  return Wide{lo, static_cast<int32_t>(hi)};
#else
  const int64_t p = static_cast<int64_t>(a) * static_cast<int64_t>(b);
  const uint64_t u = static_cast<uint64_t>(p);
  return Wide{static_cast<uint32_t>(u), static_cast<int32_t>(static_cast<uint32_t>(u >> 32))};
#endif
}

/// w / 2 (arithmetic shift of the 64-bit value by one bit, floor).
JA_FORCE_INLINE void HalveWide(Wide& w) {
#if defined(__AVR__)
  uint32_t lo = w.lo;
  uint32_t hi = static_cast<uint32_t>(w.hi);
  asm("asr %D1\n\t"
      "ror %C1\n\t"
      "ror %B1\n\t"
      "ror %A1\n\t"
      "ror %D0\n\t"
      "ror %C0\n\t"
      "ror %B0\n\t"
      "ror %A0"
      : "+r"(lo), "+r"(hi));
  w.lo = lo;
  w.hi = static_cast<int32_t>(hi);
#else
  const uint32_t uhi = static_cast<uint32_t>(w.hi);
  w.lo = (w.lo >> 1) | (uhi << 31);
  w.hi = w.hi < 0 ? static_cast<int32_t>(~(~uhi >> 1)) : static_cast<int32_t>(uhi >> 1);
#endif
}

/// w * 2 (modulo 2^64).
JA_FORCE_INLINE void DoubleWide(Wide& w) {
#if defined(__AVR__)
  uint32_t lo = w.lo;
  uint32_t hi = static_cast<uint32_t>(w.hi);
  asm("lsl %A0\n\t"
      "rol %B0\n\t"
      "rol %C0\n\t"
      "rol %D0\n\t"
      "rol %A1\n\t"
      "rol %B1\n\t"
      "rol %C1\n\t"
      "rol %D1"
      : "+r"(lo), "+r"(hi));
  w.lo = lo;
  w.hi = static_cast<int32_t>(hi);
#else
  const uint32_t uhi = static_cast<uint32_t>(w.hi);
  w.hi = static_cast<int32_t>((uhi << 1) | (w.lo >> 31));
  w.lo <<= 1;
#endif
}

/// w halved (floor) kTimes times, written out (a counted loop costs ~5 cycles per step on AVR).
template <int kTimes>
struct HalveTimes {
  static JA_FORCE_INLINE void Run(Wide& w) {
    HalveWide(w);
    HalveTimes<kTimes - 1>::Run(w);
  }
};
template <>
struct HalveTimes<0> {
  static JA_FORCE_INLINE void Run(Wide&) {}
};

/// floor(w / 2^kShift) for 0 <= kShift <= 32, exactly (arithmetic shift of the 64-bit value).
/// Whole bytes first (register moves on AVR), then at most 7 single-bit steps: avr-gcc 5.4
/// compiles a 32-bit shift by a constant that is not a multiple of 8 into a bit-by-bit loop
/// (~6 cycles per bit and word), which made every rounding of the step cost ~350 cycles.
template <int kShift>
JA_FORCE_INLINE Wide ShiftRightWide(Wide w) {
  static_assert(kShift >= 0 && kShift <= 32, "shift 0..32");
  constexpr int kBits = 8 * (kShift / 8);
  const uint32_t uhi = static_cast<uint32_t>(w.hi);
  const uint32_t sign = w.hi < 0 ? 0xFFFFFFFFu : 0u;
  Wide r = w;
  if (kBits == 32) {
    r = Wide{uhi, static_cast<int32_t>(sign)};
  } else if (kBits > 0) {
    constexpr int kB = (kBits > 0 && kBits < 32) ? kBits : 8;  // valid in dead branches
    r.lo = (w.lo >> kB) | (uhi << (32 - kB));
    r.hi = static_cast<int32_t>((uhi >> kB) | (sign << (32 - kB)));
  }
  HalveTimes<kShift % 8>::Run(r);
  return r;
}

/// Saturates a 64-bit value given as {lo, hi} to int32, counting saturations.
JA_FORCE_INLINE int32_t SaturateWide(uint32_t lo, int32_t hi) {
  // Representable iff hi is the sign extension of lo's top bit.
  if (hi == 0 && lo <= 0x7FFFFFFFu) return static_cast<int32_t>(lo);
  if (hi == -1 && lo >= 0x80000000u) return static_cast<int32_t>(lo - 0x80000000u) - 0x7FFFFFFF - 1;
  ++SaturationCount();
  return hi < 0 ? (-0x7FFFFFFF - 1) : 0x7FFFFFFF;
}

/// round(a * b / 2^F), saturated: (a*b + 2^(F-1)) >> F.
template <int F>
JA_FORCE_INLINE int32_t MultiplyQ(int32_t a, int32_t b) {
  static_assert(F > 0 && F < 32, "fraction bits must be 1..31");
  Wide p = MultiplyWide(a, b);
  // + 2^(F-1) with carry into hi (hi cannot overflow: |a*b| <= 2^62).
  const uint32_t half = static_cast<uint32_t>(1) << (F - 1);
  const uint32_t lo = p.lo + half;
  int32_t hi = p.hi + (lo < half ? 1 : 0);
  // Arithmetic >> F of the 64-bit value, as word shifts (byte moves on AVR when F % 8 == 0).
  const uint32_t r_lo = (lo >> F) | (static_cast<uint32_t>(hi) << (32 - F));
  // r_hi = hi >> F (arithmetic), written without shifting a negative value.
  const int32_t r_hi = hi < 0 ? -1 - static_cast<int32_t>(~static_cast<uint32_t>(hi) >> F)
                              : static_cast<int32_t>(static_cast<uint32_t>(hi) >> F);
  return SaturateWide(r_lo, r_hi);
}

// __builtin_*_overflow: measured faster in context on avr-gcc 5.4 than a hand-written sign test
// (EKF spike step 70.1 k vs 73.2 k cycles), because of register pressure around the branch.
JA_FORCE_INLINE int32_t AddSaturating(int32_t a, int32_t b) {
  int32_t r;
  if (__builtin_add_overflow(a, b, &r)) {
    ++SaturationCount();
    return a < 0 ? (-0x7FFFFFFF - 1) : 0x7FFFFFFF;
  }
  return r;
}

JA_FORCE_INLINE int32_t SubtractSaturating(int32_t a, int32_t b) {
  int32_t r;
  if (__builtin_sub_overflow(a, b, &r)) {
    ++SaturationCount();
    return a < 0 ? (-0x7FFFFFFF - 1) : 0x7FFFFFFF;
  }
  return r;
}

/// round(a * 2^F / b), saturated; b == 0 saturates towards the sign of a (0/0 -> 0, counted).
template <int F>
inline int32_t DivideQ(int32_t a, int32_t b) {
  if (b == 0) {
    ++SaturationCount();
    return a > 0 ? 0x7FFFFFFF : a < 0 ? (-0x7FFFFFFF - 1) : 0;
  }
  // |a| * 2^F / |b| in unsigned 64-bit, rounded half up in magnitude, sign applied after.
  const bool negative = (a < 0) != (b < 0);
  const uint64_t ua =
      a < 0 ? 0u - static_cast<uint64_t>(static_cast<int64_t>(a)) : static_cast<uint64_t>(a);
  const uint64_t ub =
      b < 0 ? 0u - static_cast<uint64_t>(static_cast<int64_t>(b)) : static_cast<uint64_t>(b);
  const uint64_t q = ((ua << F) + (ub >> 1)) / ub;
  if (!negative) {
    if (q > 0x7FFFFFFFu) {
      ++SaturationCount();
      return 0x7FFFFFFF;
    }
    return static_cast<int32_t>(q);
  }
  if (q > 0x80000000u) {
    ++SaturationCount();
    return -0x7FFFFFFF - 1;
  }
  return static_cast<int32_t>(0u - static_cast<uint32_t>(q));
}

/// Seeds of the reciprocal (ReciprocalRaw): round(2^30 / f_i), f_i = 1/2 + (i + 1/2) / 512, the
/// midpoints of 256 equal segments of [1/2, 1). Q2.30, 1 KB (flash on AVR).
JA_ROM constexpr int32_t kReciprocalSeed[256] = {
    2143297520, 2134974035, 2126714947, 2118519514, 2110387001, 2102316688, 2094307862, 2086359825,
    2078471886, 2070643367, 2062873598, 2055161921, 2047507687, 2039910256, 2032368998, 2024883292,
    2017452528, 2010076102, 2002753420, 1995483898, 1988266958, 1981102032, 1973988560, 1966925989,
    1959913775, 1952951381, 1946038279, 1939173947, 1932357870, 1925589541, 1918868460, 1912194135,
    1905566079, 1898983813, 1892446864, 1885954765, 1879507056, 1873103284, 1866743001, 1860425766,
    1854151143, 1847918702, 1841728020, 1835578677, 1829470263, 1823402368, 1817374591, 1811386537,
    1805437812, 1799528032, 1793656815, 1787823785, 1782028570, 1776270804, 1770550125, 1764866176,
    1759218604, 1753607062, 1748031205, 1742490694, 1736985194, 1731514374, 1726077909, 1720675474,
    1715306752, 1709971427, 1704669190, 1699399734, 1694162755, 1688957954, 1683785035, 1678643707,
    1673533680, 1668454670, 1663406396, 1658388579, 1653400944, 1648443220, 1643515139, 1638616435,
    1633746847, 1628906115, 1624093985, 1619310203, 1614554519, 1609826688, 1605126464, 1600453607,
    1595807878, 1591189042, 1586596865, 1582031119, 1577491575, 1572978008, 1568490197, 1564027920,
    1559590961, 1555179106, 1550792141, 1546429856, 1542092045, 1537778500, 1533489021, 1529223404,
    1524981453, 1520762971, 1516567762, 1512395637, 1508246403, 1504119874, 1500015863, 1495934187,
    1491874665, 1487837115, 1483821360, 1479827224, 1475854534, 1471903116, 1467972801, 1464063419,
    1460174804, 1456306792, 1452459218, 1448631921, 1444824741, 1441037520, 1437270102, 1433522331,
    1429794054, 1426085120, 1422395379, 1418724681, 1415072880, 1411439830, 1407825388, 1404229410,
    1400651755, 1397092284, 1393550859, 1390027342, 1386521599, 1383033494, 1379562896, 1376109672,
    1372673693, 1369254829, 1365852954, 1362467940, 1359099664, 1355748000, 1352412826, 1349094022,
    1345791466, 1342505040, 1339234626, 1335980107, 1332741367, 1329518292, 1326310769, 1323118686,
    1319941930, 1316780393, 1313633964, 1310502536, 1307386002, 1304284256, 1301197193, 1298124708,
    1295066699, 1292023064, 1288993702, 1285978512, 1282977395, 1279990254, 1277016989, 1274057506,
    1271111708, 1268179501, 1265260791, 1262355485, 1259463491, 1256584717, 1253719074, 1250866471,
    1248026819, 1245200031, 1242386020, 1239584699, 1236795982, 1234019784, 1231256022, 1228504612,
    1225765471, 1223038518, 1220323671, 1217620850, 1214929975, 1212250968, 1209583749, 1206928241,
    1204284368, 1201652052, 1199031219, 1196421793, 1193823700, 1191236866, 1188661219, 1186096686,
    1183543195, 1181000674, 1178469054, 1175948265, 1173438237, 1170938901, 1168450189, 1165972034,
    1163504368, 1161047125, 1158600240, 1156163646, 1153737280, 1151321076, 1148914972, 1146518903,
    1144132807, 1141756623, 1139390288, 1137033741, 1134686922, 1132349771, 1130022228, 1127704234,
    1125395730, 1123096658, 1120806960, 1118526580, 1116255460, 1113993544, 1111740776, 1109497102,
    1107262465, 1105036812, 1102820088, 1100612240, 1098413215, 1096222959, 1094041421, 1091868548,
    1089704289, 1087548593, 1085401409, 1083262687, 1081132377, 1079010430, 1076896795, 1074791425,
};

/// 2^kScale / ua for ua > 0, saturated to 2^31 - 1 (counted). No division: ua is normalised to
/// m = ua 2^n in [2^30, 2^31), i.e. f = m / 2^31 in [1/2, 1); a seed r0 ~ 1/f from a 256-entry
/// table, rounded to 16 bits (relative error e0 <= 2^-9 + 2^-16) gets one Newton step
/// r1 = r0 (2 - f r0) = 1/f (1 - e0^2) by two 32x16 products, so the result is low by at most
/// 1.03 2^-18 relative (+ 1 LSB of rounding), always identically on AVR and x86 (~300 cycles on
/// AVR against ~1 400 for the 64-bit division it replaces).
template <int kScale>
inline int32_t ReciprocalRaw(uint32_t ua) {
  int8_t n = 0;  // m = ua 2^n
  uint32_t m = ua;
  if (m >= 0x80000000u) {
    m >>= 1;  // drops one bit: 2^-31 relative
    n = -1;
  }
  while (m < (static_cast<uint32_t>(1) << 22)) {
    m <<= 8;
    n = static_cast<int8_t>(n + 8);
  }
  if (m < (static_cast<uint32_t>(1) << 26)) {
    m <<= 4;
    n = static_cast<int8_t>(n + 4);
  }
  while (m < (static_cast<uint32_t>(1) << 30)) {
    m <<= 1;
    n = static_cast<int8_t>(n + 1);
  }
  // The seed S ~ 2^30 / f, rounded to r0 = S / 2^16 (15 bits: r0 / 2^14 ~ 1 / f, relative error
  // e <= 2^-9 + 2^-16). f r0 / 2^14 = m r0 / 2^45 = 1 - e: E = 2^45 - m r0 = 2^45 e, |E| < 2^37.
  const int32_t seed = ReadRom(  // segment: bits 29..22 of m
      kReciprocalSeed + static_cast<uint8_t>(static_cast<uint16_t>(m >> 16) >> 6));
  const uint16_t r0 = static_cast<uint16_t>((static_cast<uint32_t>(seed) + 0x8000u) >> 16);
  const Wide p = MultiplyWide32x16(static_cast<int32_t>(m), r0);
  // E8 = floor(E / 2^8) mod 2^32 = 2^37 - floor(p / 2^8) (|E8| < 2^29; whole bytes).
  const int32_t e8 = static_cast<int32_t>(0u - ((p.lo >> 8) | (static_cast<uint32_t>(p.hi) << 24)));
  // Newton r1 = r0 (1 + e) = 1/f (1 - e^2) in Q2.30: r0 2^16 + r0 E / 2^29
  //   = r0 2^16 + 8 floor(r0 E8 / 2^24) (truncations <= 2^-26 relative). Two 32x16 products.
  const Wide c = MultiplyWide32x16(e8, r0);
  uint32_t corr = (c.lo >> 24) | (static_cast<uint32_t>(c.hi) << 8);  // floor(c / 2^24)
  corr += corr;
  corr += corr;
  corr += corr;
  const uint32_t r1 = (static_cast<uint32_t>(r0) << 16) + corr;  // < 2^31
  // 2^kScale / ua = r1 2^(kScale + n - 61).
  const int8_t shift = static_cast<int8_t>(kScale + n - 61);
  if (shift >= 0) {
    if (r1 > (static_cast<uint32_t>(0x7FFFFFFF) >> shift)) {
      ++SaturationCount();
      return 0x7FFFFFFF;
    }
    return static_cast<int32_t>(r1 << shift);
  }
  const uint8_t right = static_cast<uint8_t>(-shift);  // >= 1
  if (right >= 32) return 0;
  // round(r1 / 2^right) = floor((floor(r1 / 2^(right - 1)) + 1) / 2) (exactly): whole bytes
  // (register moves), at most 7 bit steps, then the half. (Forming 2^(right - 1) first was a
  // variable shift, i.e. a loop of up to 30 steps on avr-gcc 5.4.)
  uint32_t v = r1;
  uint8_t k = static_cast<uint8_t>(right - 1);
  if (k >= 16) {
    v >>= 16;
    k = static_cast<uint8_t>(k - 16);
  }
  if (k >= 8) {
    v >>= 8;
    k = static_cast<uint8_t>(k - 8);
  }
  while (k--) v >>= 1;
  return static_cast<int32_t>((v + 1u) >> 1);  // r1 < 2^31: no overflow
}

/// floor(sqrt(v)) of a 32-bit unsigned integer, bit by bit (16 rounds of shifts and one
/// compare: ~600 AVR cycles, no multiply, identical on AVR and x86).
inline uint16_t IntegerSqrt(uint32_t v) {
  uint32_t root = 0;
  uint32_t bit = static_cast<uint32_t>(1) << 30;
  while (bit > v) bit >>= 2;
  while (bit != 0) {
    if (v >= root + bit) {
      v -= root + bit;
      root = (root >> 1) + bit;
    } else {
      root >>= 1;
    }
    bit >>= 2;
  }
  return static_cast<uint16_t>(root);
}

/// sqrt(ua 2^kScale) for ua >= 0 and an even kScale >= 0, truncated, as int32: ua is shifted
/// left by the smallest even count k <= kScale that brings it to [2^30, 2^32), and the 16-bit
/// root of that shifted left by (kScale - k) / 2: relative error below 2^-15 (+ 1 LSB), enough
/// for the start-up measurement it serves (ReleaseSum); saturated (counted) >= 2^31.
template <int kScale>
inline int32_t SqrtRaw(uint32_t ua) {
  static_assert(kScale >= 0 && kScale % 2 == 0, "SqrtRaw: an even, non-negative scale");
  uint8_t k = 0;
  while (k + 2 <= kScale && ua < (static_cast<uint32_t>(1) << 30)) {
    ua <<= 2;
    k = static_cast<uint8_t>(k + 2);
  }
  const uint32_t root = IntegerSqrt(ua);
  const uint8_t up = static_cast<uint8_t>((kScale - k) / 2);
  if (up >= 16 || (up != 0 && root >= (static_cast<uint32_t>(1) << (31 - up)))) {
    ++SaturationCount();
    return 0x7FFFFFFF;
  }
  return static_cast<int32_t>(root << up);
}

}  // namespace detail

/// A real number in Q(31-F).F: raw int32 = round(value * 2^F).
template <int F>
class Fixed {
 public:
  static_assert(F > 0 && F < 31, "Fixed<F>: F fraction bits, 1..30");
  static constexpr int kFractionBits = F;
  static constexpr int32_t kOneRaw = static_cast<int32_t>(1) << F;

  constexpr Fixed() : raw_(0) {}
  /// From an integer (saturating). Explicit: Eigen writes Scalar(0), Scalar(1).
  constexpr explicit Fixed(int v) : raw_(FromInt(v)) {}
  /// From a float (round half up, saturating; NaN -> 0). For configuration, not the hot path.
  explicit Fixed(float v) : raw_(FromFloat(v)) {}
  explicit Fixed(double v) : raw_(FromFloat(static_cast<float>(v))) {}

  static constexpr Fixed FromRaw(int32_t raw) { return Fixed(raw, RawTag()); }
  constexpr int32_t raw() const { return raw_; }
  float ToFloat() const { return static_cast<float>(raw_) * (1.0f / static_cast<float>(kOneRaw)); }
  explicit operator float() const { return ToFloat(); }

  friend Fixed operator+(Fixed a, Fixed b) {
    return FromRaw(detail::AddSaturating(a.raw_, b.raw_));
  }
  friend Fixed operator-(Fixed a, Fixed b) {
    return FromRaw(detail::SubtractSaturating(a.raw_, b.raw_));
  }
  friend Fixed operator-(Fixed a) { return FromRaw(detail::SubtractSaturating(0, a.raw_)); }
  friend Fixed operator*(Fixed a, Fixed b) { return FromRaw(detail::MultiplyQ<F>(a.raw_, b.raw_)); }
  friend Fixed operator/(Fixed a, Fixed b) { return FromRaw(detail::DivideQ<F>(a.raw_, b.raw_)); }
  Fixed& operator+=(Fixed b) { return *this = *this + b; }
  Fixed& operator-=(Fixed b) { return *this = *this - b; }
  Fixed& operator*=(Fixed b) { return *this = *this * b; }
  Fixed& operator/=(Fixed b) { return *this = *this / b; }
  friend constexpr bool operator==(Fixed a, Fixed b) { return a.raw_ == b.raw_; }
  friend constexpr bool operator!=(Fixed a, Fixed b) { return a.raw_ != b.raw_; }
  friend constexpr bool operator<(Fixed a, Fixed b) { return a.raw_ < b.raw_; }
  friend constexpr bool operator>(Fixed a, Fixed b) { return a.raw_ > b.raw_; }
  friend constexpr bool operator<=(Fixed a, Fixed b) { return a.raw_ <= b.raw_; }
  friend constexpr bool operator>=(Fixed a, Fixed b) { return a.raw_ >= b.raw_; }

 private:
  struct RawTag {};
  constexpr Fixed(int32_t raw, RawTag) : raw_(raw) {}
  static constexpr int32_t FromInt(int v) {
    // v * 2^F saturated; int is 16 bits on AVR, 32 on x86.
    return static_cast<int32_t>(v) > (0x7FFFFFFF >> F) ? 0x7FFFFFFF
           : static_cast<int32_t>(v) < ((-0x7FFFFFFF - 1) >> F)
               ? (-0x7FFFFFFF - 1)
               : static_cast<int32_t>(static_cast<uint32_t>(v) << F);
  }
  static int32_t FromFloat(float v) {
    const float scaled = v * static_cast<float>(kOneRaw) + 0.5f;
    if (!(scaled == scaled)) return 0;                    // NaN
    if (scaled >= 2147483648.0f) return 0x7FFFFFFF;       // also +inf
    if (scaled < -2147483648.0f) return -0x7FFFFFFF - 1;  // also -inf
    // floor() without libm: truncate, then step down for negative non-integers.
    int32_t t = static_cast<int32_t>(scaled);
    if (static_cast<float>(t) > scaled) --t;
    return t;
  }
  int32_t raw_;
};

/// Sum of products with one rounding: the 64-bit products are added exactly and rounded and
/// saturated once in Result() (a dot product costs one rounding instead of one per term, and
/// no per-term saturation test). Float has the same interface (scalar_math.hpp), so filter code
/// written with accumulators instantiates with both.
template <class S>
class Accumulator;

template <int F>
class Accumulator<Fixed<F>> {
 public:
  /// sum += a * b (exact, 64-bit; wraps only beyond 2^63, i.e. never for 2^31-bounded terms
  /// summed fewer than 2 times).
  JA_FORCE_INLINE void Add(Fixed<F> a, Fixed<F> b) {
    const detail::Wide p = detail::MultiplyWide(a.raw(), b.raw());
    AddWide(p.lo, p.hi);
  }
  /// sum -= a * b.
  JA_FORCE_INLINE void Subtract(Fixed<F> a, Fixed<F> b) {
    const detail::Wide p = detail::MultiplyWide(a.raw(), b.raw());
    // -(hi:lo) = (~hi + carry):(~lo + 1)
    const uint32_t lo = ~p.lo + 1u;
    const int32_t hi = static_cast<int32_t>(~static_cast<uint32_t>(p.hi) + (lo == 0 ? 1u : 0u));
    AddWide(lo, hi);
  }
  /// sum += v (v scaled up by 2^F to the product scale).
  JA_FORCE_INLINE void AddValue(Fixed<F> v) {
    const uint32_t raw = static_cast<uint32_t>(v.raw());
    AddWide(raw << F, v.raw() < 0 ? static_cast<int32_t>(~(~raw >> (32 - F)))
                                  : static_cast<int32_t>(raw >> (32 - F)));
  }
  /// round(sum / 2^F), saturated (counted).
  Fixed<F> Result() const {
    const uint32_t half = static_cast<uint32_t>(1) << (F - 1);
    const uint32_t lo = lo_ + half;
    const int32_t hi = static_cast<int32_t>(static_cast<uint32_t>(hi_) + (lo < half ? 1u : 0u));
    const uint32_t r_lo = (lo >> F) | (static_cast<uint32_t>(hi) << (32 - F));
    const int32_t r_hi = hi < 0 ? -1 - static_cast<int32_t>(~static_cast<uint32_t>(hi) >> F)
                                : static_cast<int32_t>(static_cast<uint32_t>(hi) >> F);
    return Fixed<F>::FromRaw(detail::SaturateWide(r_lo, r_hi));
  }

 private:
  JA_FORCE_INLINE void AddWide(uint32_t lo, int32_t hi) {
    const uint32_t sum = lo_ + lo;
    hi_ = static_cast<int32_t>(static_cast<uint32_t>(hi_) + static_cast<uint32_t>(hi) +
                               (sum < lo ? 1u : 0u));  // modulo 2^64, no signed overflow
    lo_ = sum;
  }
  uint32_t lo_ = 0;
  int32_t hi_ = 0;
};

template <int F>
inline Fixed<F> abs(Fixed<F> x) {
  return x.raw() < 0 ? -x : x;
}

/// Re-expresses x with G fraction bits (round half up when dropping bits, saturating).
template <int G, int F>
inline Fixed<G> ConvertFixed(Fixed<F> x) {
  if (G == F) return Fixed<G>::FromRaw(x.raw());
  if (G < F) {
    // round half up: floor((x + 2^(s-1)) / 2^s) = floor(x / 2^s) + bit s-1 of x, exactly (x =
    // q 2^s + r: the half carries into q iff r >= 2^(s-1)); t = floor(x / 2^(s-1)) is one
    // arithmetic shift, then floor(t / 2) + (t & 1). No overflow, no saturation.
    constexpr int kShift = (F - G) > 0 && (F - G) < 32 ? (F - G) : 1;
    const int32_t raw = x.raw();
    // floor(raw / 2^(s-1)) without shifting a negative value
    const int32_t t = raw < 0
                          ? -1 - static_cast<int32_t>(~static_cast<uint32_t>(raw) >> (kShift - 1))
                          : static_cast<int32_t>(static_cast<uint32_t>(raw) >> (kShift - 1));
    const int32_t half_t = t < 0 ? -1 - static_cast<int32_t>(~static_cast<uint32_t>(t) >> 1)
                                 : static_cast<int32_t>(static_cast<uint32_t>(t) >> 1);
    return Fixed<G>::FromRaw(half_t + static_cast<int32_t>(static_cast<uint32_t>(t) & 1u));
  }
  constexpr int kShift = (G - F) > 0 ? (G - F) : 1;
  const int32_t limit = static_cast<int32_t>(0x7FFFFFFF >> kShift);
  if (x.raw() > limit || x.raw() < -limit - 1) {
    ++SaturationCount();
    return Fixed<G>::FromRaw(x.raw() < 0 ? (-0x7FFFFFFF - 1) : 0x7FFFFFFF);
  }
  return Fixed<G>::FromRaw(static_cast<int32_t>(static_cast<uint32_t>(x.raw()) << kShift));
}

}  // namespace core
}  // namespace ja
