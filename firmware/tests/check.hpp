// Minimal test macros for the firmware's x86 tests: every failed CHECK prints file:line and the
// expression, and the test binary exits non-zero at the end (RunTests).
#pragma once

#include <cmath>
#include <cstdio>

namespace ja_test {
inline int& Failures() {
  static int failures = 0;
  return failures;
}
inline bool Report(bool ok, const char* expr, const char* file, int line) {
  if (!ok) {
    ++Failures();
    std::fprintf(stderr, "%s:%d: CHECK failed: %s\n", file, line, expr);
  }
  return ok;
}
inline int Finish(const char* name) {
  if (Failures()) {
    std::fprintf(stderr, "%s: %d check(s) failed\n", name, Failures());
    return 1;
  }
  std::printf("%s: all checks passed\n", name);
  return 0;
}
}  // namespace ja_test

#define CHECK(expr) ja_test::Report(static_cast<bool>(expr), #expr, __FILE__, __LINE__)
#define CHECK_EQ(a, b) ja_test::Report((a) == (b), #a " == " #b, __FILE__, __LINE__)
#define CHECK_NEAR(a, b, tol)                                                          \
  ja_test::Report(std::fabs(static_cast<double>(a) - static_cast<double>(b)) <= (tol), \
                  #a " ~= " #b " within " #tol, __FILE__, __LINE__)
