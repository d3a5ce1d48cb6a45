"""Cycle estimate of the recommended 16-bit operand set (REC2), per step, AVR.
Costs: 32x32 product 85, 32x16 45, 16x16 20 (MULs + column adds only);
A = applying a runtime exponent to one result/operand (variable shift of a 4-6 byte value, beyond
the constant rounding shift it replaces), X = extracting a rounded 16-bit mantissa from a 32/48-bit
value (a variable shift), N = finding a vector's exponent (OR of |entries|, leading-bit search)."""
P32, P3216, P1616 = 85, 45, 20
# item: (to 32x16, to 16x16, N, X, A, other) per rig set
ITEMS = {
 "scenario": {
  "(a) sin/cos sign + Q0.16 magnitude (fixed)":            (6, 0, 0, 0, 0, 6 * 3),
  "(e) G, F, dT*G_a rows: 16-bit mantissa, exp per row":    (16, 0, 0, 0, 8, 0),
  "(g) dT unsigned 16-bit mantissa (runtime exponent)":     (6, 0, 0, 0, 6, 0),
  "(b) k: 16-bit mantissas, 1 exp/update (pre-shift p, nu)": (21, 0, 3, 8, 10, 0),
  "(c) 1/s, 1/D: 16-bit mantissas (reciprocal keeps exp)":   (13, 0, 0, 3, 2, -3 * 30),
  "(d) h~ z1, z2: split exps (omega part / theta entry)":    (25, 0, 4, 5, 20, 0),
 },
 "general": {
  "(a) sin/cos sign + Q0.16 magnitude (fixed)":            (8, 3, 0, 0, 0, 11 * 3),
  "(e) G, F, dT*G_a rows: 16-bit mantissa, exp per row":    (32, 0, 0, 0, 8, 0),
  "(g) dT unsigned 16-bit mantissa (runtime exponent)":     (6, 0, 0, 0, 6, 0),
  "(b) k: 16-bit mantissas, 1 exp/update (pre-shift p, nu)": (21, 0, 3, 8, 10, 0),
  "(c) 1/s, 1/D: 16-bit mantissas (reciprocal keeps exp)":   (17, 0, 0, 6, 3, -6 * 30),
  "(d) h~ z1, z2: split exps (omega part / theta entry)":    (25, 0, 4, 5, 20, 0),
 }}
for A in (15, 25, 35):
    X, N = A, 30
    for rig, items in ITEMS.items():
        tot_g = tot_n = n16 = n1616 = 0
        print(f"--- {rig} rigs, A = X = {A}, N = {N}")
        for name, (a, b, n, x, aa, other) in items.items():
            gross = a * (P32 - P3216) + b * (P32 - P1616)
            cost = n * N + x * X + aa * A + other
            tot_g += gross; tot_n += gross - cost; n16 += a; n1616 += b
            print(f"  {name:<58} {a:3d}+{b} products  gross -{gross:5d}  exp cost +{cost:4d}  net {-(gross - cost):+6d}")
        print(f"  TOTAL {n16} to 32x16, {n1616} to 16x16: gross -{tot_g}, net -{tot_n}")
