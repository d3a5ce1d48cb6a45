// Fixed<F> as an Eigen scalar: NumTraits so Matrix<Fixed<F>, R, C> works with Eigen's
// fixed-size expressions (products, sums, transposes, blocks).
#pragma once

#include "config.hpp"
#include "fixed_point.hpp"

namespace Eigen {

template <int F>
struct NumTraits<ja::core::Fixed<F>> : GenericNumTraits<ja::core::Fixed<F>> {
  using Scalar = ja::core::Fixed<F>;
  using Real = Scalar;
  using NonInteger = Scalar;
  using Literal = Scalar;
  using Nested = Scalar;
  enum {
    IsComplex = 0,
    IsInteger = 0,
    IsSigned = 1,
    RequireInitialization = 1,
    ReadCost = 1,
    AddCost = 2,
    MulCost = 8,  // relative: on AVR a product is ~35x an add (NUMERICS.md)
  };
  static inline Scalar epsilon() { return Scalar::FromRaw(1); }
  static inline Scalar dummy_precision() { return Scalar::FromRaw(16); }
  static inline Scalar highest() { return Scalar::FromRaw(0x7FFFFFFF); }
  static inline Scalar lowest() { return Scalar::FromRaw(-0x7FFFFFFF - 1); }
  static inline int digits10() { return (F * 3) / 10; }
};

}  // namespace Eigen
