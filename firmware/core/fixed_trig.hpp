// Fixed-point sin, cos and atan2 by table and linear interpolation (no libm, no library
// division: atan2's one division is a 16-bit long division). Tables are 257 int32 entries in
// Q2.30, in flash on AVR (JA_ROM).
//
// sin: the angle becomes a phase p = angle / 2pi as a uint32 fraction of a turn (wraps for free);
// the top 2 bits pick the quadrant, the next 8 the segment i, the low 22 the position u in it:
//   sin(q) ~ T[i] + (T[i+1] - T[i]) * u / 2^22,   T[i] = sin(i * (pi/2) / 256) * 2^30.
// Interpolation error <= h^2/8 with h = pi/512: 4.7e-6; table rounding 1e-9.
// atan2: reduce (y, x) to the first octant, t = min/max in Q16 (a 16-bit long division after
// normalising max into [2^14, 2^15)), atan(t) from the table A[i] = atan(i/256) * 2^30, then undo
// the octant: error ~1e-5 rad (dominated by the 15-bit normalised ratio).
#pragma once

#include <stdint.h>

#include "config.hpp"
#include "fixed_point.hpp"

namespace ja {
namespace core {
namespace detail {

JA_ROM constexpr int32_t kSinTable[257] = {
    0,          6588356,    13176464,   19764076,   26350943,   32936819,   39521455,   46104602,
    52686014,   59265442,   65842639,   72417357,   78989349,   85558366,   92124163,   98686491,
    105245103,  111799753,  118350194,  124896179,  131437462,  137973796,  144504935,  151030634,
    157550647,  164064728,  170572633,  177074115,  183568930,  190056834,  196537583,  203010932,
    209476638,  215934457,  222384147,  228825464,  235258165,  241682010,  248096755,  254502159,
    260897982,  267283981,  273659918,  280025552,  286380643,  292724951,  299058239,  305380268,
    311690799,  317989595,  324276419,  330551034,  336813204,  343062693,  349299266,  355522689,
    361732726,  367929144,  374111709,  380280190,  386434353,  392573967,  398698801,  404808624,
    410903207,  416982319,  423045732,  429093217,  435124548,  441139496,  447137835,  453119340,
    459083786,  465030947,  470960600,  476872522,  482766489,  488642281,  494499676,  500338453,
    506158392,  511959275,  517740883,  523502998,  529245404,  534967884,  540670223,  546352205,
    552013618,  557654248,  563273883,  568872310,  574449320,  580004702,  585538248,  591049748,
    596538995,  602005783,  607449906,  612871159,  618269338,  623644239,  628995660,  634323400,
    639627258,  644907034,  650162530,  655393548,  660599890,  665781362,  670937767,  676068911,
    681174602,  686254647,  691308855,  696337036,  701339000,  706314559,  711263525,  716185713,
    721080937,  725949013,  730789757,  735602987,  740388522,  745146182,  749875788,  754577161,
    759250125,  763894504,  768510122,  773096806,  777654384,  782182683,  786681534,  791150767,
    795590213,  799999706,  804379079,  808728167,  813046808,  817334838,  821592095,  825818421,
    830013654,  834177638,  838310216,  842411232,  846480531,  850517961,  854523370,  858496606,
    862437520,  866345964,  870221790,  874064853,  877875009,  881652112,  885396022,  889106597,
    892783698,  896427186,  900036924,  903612776,  907154608,  910662286,  914135678,  917574653,
    920979082,  924348837,  927683790,  930983817,  934248793,  937478595,  940673101,  943832191,
    946955747,  950043650,  953095785,  956112036,  959092290,  962036435,  964944360,  967815955,
    970651112,  973449725,  976211688,  978936898,  981625251,  984276646,  986890984,  989468165,
    992008094,  994510675,  996975812,  999403415,  1001793390, 1004145648, 1006460100, 1008736660,
    1010975242, 1013175761, 1015338134, 1017462281, 1019548121, 1021595575, 1023604567, 1025575020,
    1027506862, 1029400018, 1031254418, 1033069992, 1034846671, 1036584389, 1038283080, 1039942680,
    1041563127, 1043144360, 1044686319, 1046188946, 1047652185, 1049075980, 1050460278, 1051805027,
    1053110176, 1054375676, 1055601479, 1056787540, 1057933813, 1059040255, 1060106826, 1061133483,
    1062120190, 1063066909, 1063973603, 1064840240, 1065666786, 1066453210, 1067199483, 1067905576,
    1068571464, 1069197120, 1069782521, 1070327646, 1070832474, 1071296985, 1071721163, 1072104991,
    1072448455, 1072751542, 1073014240, 1073236540, 1073418433, 1073559913, 1073660973, 1073721611,
    1073741824,
};

JA_ROM constexpr int32_t kAtanTable[257] = {
    0,         4194283,   8388437,   12582336,  16775851,  20968854,  25161218,  29352814,
    33543516,  37733196,  41921726,  46108981,  50294833,  54479155,  58661822,  62842708,
    67021687,  71198634,  75373424,  79545932,  83716036,  87883610,  92048532,  96210679,
    100369930, 104526161, 108679253, 112829084, 116975536, 121118487, 125257820, 129393416,
    133525159, 137652930, 141776614, 145896097, 150011262, 154121996, 158228185, 162329719,
    166426484, 170518371, 174605269, 178687069, 182763663, 186834944, 190900805, 194961140,
    199015846, 203064818, 207107953, 211145151, 215176309, 219201328, 223220110, 227232556,
    231238569, 235238055, 239230917, 243217063, 247196400, 251168835, 255134279, 259092643,
    263043837, 266987774, 270924369, 274853536, 278775192, 282689253, 286595638, 290494267,
    294385059, 298267937, 302142824, 306009643, 309868320, 313718782, 317560955, 321394768,
    325220151, 329037035, 332845353, 336645037, 340436023, 344218245, 347991640, 351756148,
    355511705, 359258254, 362995735, 366724092, 370443267, 374153206, 377853855, 381545162,
    385227074, 388899541, 392562515, 396215946, 399859787, 403493994, 407118521, 410733324,
    414338361, 417933591, 421518973, 425094468, 428660037, 432215645, 435761254, 439296830,
    442822340, 446337750, 449843028, 453338145, 456823070, 460297774, 463762232, 467216414,
    470660297, 474093856, 477517067, 480929907, 484332355, 487724391, 491105994, 494477146,
    497837829, 501188027, 504527723, 507856902, 511175551, 514483656, 517781204, 521068185,
    524344587, 527610402, 530865619, 534110231, 537344232, 540567613, 543780370, 546982499,
    550173994, 553354853, 556525073, 559684652, 562833591, 565971887, 569099543, 572216558,
    575322936, 578418678, 581503788, 584578271, 587642129, 590695370, 593737999, 596770023,
    599791448, 602802283, 605802536, 608792216, 611771334, 614739898, 617697921, 620645413,
    623582386, 626508854, 629424828, 632330323, 635225352, 638109930, 640984073, 643847795,
    646701114, 649544044, 652376604, 655198810, 658010682, 660812236, 663603492, 666384468,
    669155185, 671915663, 674665921, 677405981, 680135863, 682855589, 685565182, 688264663,
    690954054, 693633380, 696302662, 698961924, 701611191, 704250487, 706879836, 709499262,
    712108791, 714708448, 717298260, 719878250, 722448447, 725008876, 727559563, 730100536,
    732631822, 735153448, 737665442, 740167831, 742660643, 745143906, 747617650, 750081902,
    752536690, 754982045, 757417995, 759844569, 762261796, 764669707, 767068330, 769457696,
    771837835, 774208776, 776570551, 778923188, 781266719, 783601175, 785926586, 788242982,
    790550395, 792848855, 795138394, 797419043, 799690833, 801953796, 804207961, 806453363,
    808690030, 810917996, 813137292, 815347949, 817549999, 819743474, 821928406, 824104826,
    826272767, 828432260, 830583337, 832726030, 834860371, 836986393, 839104126, 841213603,
    843314857,
};

/// Linear interpolation in a 257-entry table: T[i] + (T[i+1] - T[i]) * u / 2^16, u < 2^16. Q30.
inline int32_t InterpolateTable(const int32_t* table, uint8_t i, uint16_t u16) {
  const int32_t a = ReadRom(table + i);
  const int32_t b = ReadRom(table + i + 1);
  // (b - a) * u: |b - a| < 2^23 and u < 2^16, so the product fits in 40 bits; >> 16 rounded
  // (byte moves on AVR).
  const Wide p = MultiplyWide32x16(b - a, u16);  // exact, 8 MULs on AVR
  const uint32_t lo = p.lo + 0x8000u;
  const int32_t hi = p.hi + (lo < 0x8000u ? 1 : 0);
  const int32_t delta = static_cast<int32_t>((lo >> 16) | (static_cast<uint32_t>(hi) << 16));
  return a + delta;
}

/// sin of a phase (fraction of a turn, 2^32 = 2pi) in Q30.
inline int32_t SinPhaseQ30(uint32_t phase) {
  // The top byte, then its top 2 bits (phase >> 30 is a 30-step bit loop on avr-gcc 5.4).
  const uint8_t quadrant = static_cast<uint8_t>(static_cast<uint8_t>(phase >> 24) >> 6);
  uint32_t in_quadrant = phase & 0x3FFFFFFFu;
  if (quadrant & 1u) in_quadrant = 0x40000000u - in_quadrant;  // sin(pi - q) = sin(q)
  // in_quadrant in [0, 2^30]: segment = bits 29..22, u = bits 21..6 (2^30 -> the last entry).
  if (in_quadrant == 0x40000000u)
    return (quadrant & 2u) ? -ReadRom(kSinTable + 256) : ReadRom(kSinTable + 256);
  const uint32_t v = in_quadrant << 2;  // segment in the top byte, u in the next two
  const int32_t s =
      InterpolateTable(kSinTable, static_cast<uint8_t>(v >> 24), static_cast<uint16_t>(v >> 8));
  return (quadrant & 2u) ? -s : s;
}

/// Converts Q30 to Q(F) with rounding (F <= 30).
template <int F>
inline int32_t FromQ30(int32_t v) {
  if (F == 30) return v;
  constexpr int kShift = F < 30 ? 30 - F : 1;
  // floor((v + 2^(kShift-1)) / 2^kShift) without shifting a negative value.
  const int32_t biased = v + (static_cast<int32_t>(1) << (kShift - 1));
  return biased < 0 ? -1 - static_cast<int32_t>(~static_cast<uint32_t>(biased) >> kShift)
                    : static_cast<int32_t>(static_cast<uint32_t>(biased) >> kShift);
}

/// Phase (2^32 per turn) of an angle in radians held as Q(F): angle * 2^32 / (2 pi), mod 2^32.
template <int F>
inline uint32_t PhaseOf(int32_t angle_raw) {
  // 2^32 / (2 pi) * 2^(32 - F) would overflow; use K = round(2^32/(2 pi)) and >> F of the
  // 64-bit product, keeping the low 32 bits (the wrap is the modulo).
  constexpr int32_t kTurnsPerRadianQ32 = 683565276;  // 2^32 / (2 pi)
  // (lo >> F) | (hi << (32 - F)) by whole bytes + bit steps (a 32-bit shift by 28 is a 28-step
  // loop on avr-gcc 5.4).
  return ShiftRightWide<F>(MultiplyWide(angle_raw, kTurnsPerRadianQ32)).lo;
}

}  // namespace detail

/// sin(angle), angle in radians. |error| <= 5e-6 + 1 LSB.
template <int F>
inline Fixed<F> Sin(Fixed<F> angle_rad) {
  return Fixed<F>::FromRaw(
      detail::FromQ30<F>(detail::SinPhaseQ30(detail::PhaseOf<F>(angle_rad.raw()))));
}

/// cos(angle) = sin(angle + pi/2), angle in radians.
template <int F>
inline Fixed<F> Cos(Fixed<F> angle_rad) {
  return Fixed<F>::FromRaw(
      detail::FromQ30<F>(detail::SinPhaseQ30(detail::PhaseOf<F>(angle_rad.raw()) + 0x40000000u)));
}

/// sin and cos of one angle (one phase computation; identical to Sin and Cos).
template <int F>
inline void SinCos(Fixed<F> angle_rad, Fixed<F>& s, Fixed<F>& c) {
  const uint32_t phase = detail::PhaseOf<F>(angle_rad.raw());
  s = Fixed<F>::FromRaw(detail::FromQ30<F>(detail::SinPhaseQ30(phase)));
  c = Fixed<F>::FromRaw(detail::FromQ30<F>(detail::SinPhaseQ30(phase + 0x40000000u)));
}

/// atan2(y, x) in radians as R = Fixed<G> (any G <= 29: no detour through the inputs' format),
/// in (-pi, pi]; atan2(0, 0) = 0. |error| <= ~2e-5 rad.
template <class R, int F>
inline R Atan2To(Fixed<F> y, Fixed<F> x) {
  constexpr int G = R::kFractionBits;
  static_assert(G <= 29, "Atan2: the result needs pi to be representable");
  // |y|, |x| as uint32 (the most negative raw has a magnitude of 2^31, still representable).
  const uint32_t ay =
      y.raw() < 0 ? 0u - static_cast<uint32_t>(y.raw()) : static_cast<uint32_t>(y.raw());
  const uint32_t ax =
      x.raw() < 0 ? 0u - static_cast<uint32_t>(x.raw()) : static_cast<uint32_t>(x.raw());
  if (ax == 0 && ay == 0) return R();
  const bool swap = ay > ax;  // octant: t = min/max <= 1
  uint32_t num = swap ? ax : ay;
  uint32_t den = swap ? ay : ax;
  // Normalise den into [2^14, 2^15): then (num << 16) / den < 2^17 fits 32-bit arithmetic.
  while (den >= (static_cast<uint32_t>(1) << 15)) {
    den >>= 1;
    num >>= 1;
  }
  while (den < (static_cast<uint32_t>(1) << 14)) {
    den <<= 1;
    num <<= 1;
  }
  // t = floor((num 2^16 + den / 2) / den) in [0, 2^16] by 17 steps of long division on 16-bit
  // words (num <= den < 2^15, so the remainder stays below den and fits 16 bits); exactly the
  // 32/32 division's quotient (libgcc's __udivmodsi4 runs 32 steps on 32-bit words on AVR).
  const uint32_t dividend = (num << 16) + (den >> 1);
  const uint16_t d16 = static_cast<uint16_t>(den);
  uint16_t rem = static_cast<uint16_t>(dividend >> 16);
  uint16_t low = static_cast<uint16_t>(dividend);
  uint32_t t_q16 = 0;
  if (rem >= d16) {
    rem = static_cast<uint16_t>(rem - d16);
    t_q16 = 1;
  }
  for (uint8_t i = 0; i < 16; ++i) {
    rem = static_cast<uint16_t>((rem << 1) | (low >> 15));
    low = static_cast<uint16_t>(low << 1);
    t_q16 += t_q16;
    if (rem >= d16) {
      rem = static_cast<uint16_t>(rem - d16);
      t_q16 |= 1u;
    }
  }
  // Table index over [0, 1]: i = t * 256, u = remainder in 2^16 units.
  int32_t a = t_q16 >= 0x10000u
                  ? ReadRom(detail::kAtanTable + 256)
                  : detail::InterpolateTable(detail::kAtanTable, static_cast<uint8_t>(t_q16 >> 8),
                                             static_cast<uint16_t>(t_q16 << 8));
  // Undo the octant (all in Q30; pi/2 = 1686629713, pi = 3373259426 > int32: handled below).
  constexpr int32_t kHalfPiQ30 = 1686629713;
  if (swap) a = kHalfPiQ30 - a;  // angle in [0, pi/2]
  const int32_t a_f = detail::FromQ30<G>(a);
  constexpr int32_t kPiRaw = static_cast<int32_t>(
      (static_cast<int64_t>(3373259426LL) + (static_cast<int64_t>(1) << (29 - G))) >> (30 - G));
  int32_t r = x.raw() < 0 ? kPiRaw - a_f : a_f;  // quadrant II: pi - a
  if (y.raw() < 0) r = -r;
  return R::FromRaw(r);
}

/// atan2(y, x) in radians in the inputs' format.
template <int F>
inline Fixed<F> Atan2(Fixed<F> y, Fixed<F> x) {
  return Atan2To<Fixed<F>>(y, x);
}

}  // namespace core
}  // namespace ja
