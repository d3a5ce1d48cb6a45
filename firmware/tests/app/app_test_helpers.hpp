// What the application tests (test_app_*.cpp, one file per section of firmware/app/APP.md) share
// over the fakes of app_fakes.hpp: the factory rig and the mixed rig, start_stream, a static pose
// and the estimated angle in degrees.
#pragma once

#include <math.h>
#include <stdint.h>

#include <memory>

#include "app_fakes.hpp"

namespace ja_test {

constexpr uint8_t kAdxl345 = static_cast<uint8_t>(proto::SensorModel::kAdxl345);
constexpr uint8_t kAdxl357 = static_cast<uint8_t>(proto::SensorModel::kAdxl357);
constexpr uint8_t kBno055 = static_cast<uint8_t>(proto::SensorModel::kBno055);
constexpr float kG = 9.80665f;
constexpr double kPi = 3.14159265358979;

/// The factory rig: ADXL345s (0x53) on multiplexer channels 0-3, links a (0, 1) and b (2, 3).
inline std::unique_ptr<Board> MakeBoard() {
  std::unique_ptr<Board> b(new Board());
  b->AddDefaultChips();
  return b;
}

/// The mixed rig: ADXL345s (0x53) on channels 0 and 2, an ADXL357 (0x1D) on 1, a BNO055 (0x28)
/// on 3.
inline std::unique_ptr<Board> MakeMixedBoard() {
  std::unique_ptr<Board> b(new Board());
  b->bus.Add(kAdxl345, 0x53, 0);
  b->bus.Add(kAdxl357, 0x1D, 1);
  b->bus.Add(kAdxl345, 0x53, 2);
  b->bus.Add(kBno055, 0x28, 3);
  return b;
}

/// The paired rig: two ADXL345 a channel, 0x53 and 0x1D, link a on channel 0, b on 1 (two
/// multiplexer selects a loop instead of four). SetPairedSensors configures it.
inline std::unique_ptr<Board> MakePairedBoard() {
  std::unique_ptr<Board> b(new Board());
  for (int ch = 0; ch < 2; ++ch) {
    b->bus.Add(kAdxl345, 0x53, ch);
    b->bus.Add(kAdxl345, 0x1D, ch);
  }
  return b;
}

/// Commands the paired rig's four slots (the factory positions: 4.75 cm and 27.5 cm along x).
inline void SetPairedSensors(Board& b) {
  for (uint8_t i = 0; i < 4; ++i) {
    proto::SetSensor s = {};
    s.slot = i;
    s.count = 4;
    s.link = static_cast<uint8_t>(i / 2);
    s.model = kAdxl345;
    s.mux_channel = static_cast<uint8_t>(i / 2);
    s.address = i % 2 == 0 ? 0x53 : 0x1D;
    s.range_g = 4;
    s.x = i % 2 == 0 ? 47500 : 275000;
    b.Command(s);
  }
}

/// Begin, then the paired rig's slots commanded and taken.
inline void BeginPaired(Board& b, ja::app::App& app) {
  app.Begin();
  SetPairedSensors(b);
  b.Run(app, 20000);
}

/// Commands the mixed rig's slots 1 (ADXL357, +-10 g, link a) and 3 (BNO055, +-4 g, link b);
/// the two commands' seqs in q.
inline void SetMixedSensors(Board& b, uint16_t q[2]) {
  proto::SetSensor s = {};
  s.slot = 1;
  s.count = 4;
  s.link = 0;
  s.model = kAdxl357;
  s.mux_channel = 1;
  s.address = 0x1D;
  s.range_g = 10;
  s.x = 275000;
  q[0] = b.Command(s);
  s.slot = 3;
  s.link = 1;
  s.model = kBno055;
  s.mux_channel = 3;
  s.address = 0x28;
  s.range_g = 4;
  q[1] = b.Command(s);
}

/// start_stream with `mode` every loop, status every `status_ms` (0: on change only).
inline proto::StartStream Stream(uint8_t mode, uint16_t status_ms = 0) {
  proto::StartStream m = {};
  m.every = 1;
  m.mode = mode;
  m.status_interval_ms = status_ms;
  return m;
}

/// Static pose with gravity in the plane: link a's sensors read f_a, link b's R(theta)^T f_a.
inline void SetStaticPose(Board& b, double theta_rad) {
  const float fa[2] = {0.6f * kG, 0.8f * kG};
  const float c = static_cast<float>(cos(theta_rad)), s = static_cast<float>(sin(theta_rad));
  const float fb[2] = {c * fa[0] - s * fa[1], s * fa[0] + c * fa[1]};
  for (int i = 0; i < 4; ++i) {
    const float* f = i < 2 ? fa : fb;
    b.bus.chips[i].force_mps2[0] = f[0];
    b.bus.chips[i].force_mps2[1] = f[1];
    b.bus.chips[i].force_mps2[2] = 0.1f * kG;
  }
}

/// The estimate's theta (Q24 rad) in degrees.
inline double ThetaDeg(const proto::SampleEstimate& m) {
  return m.theta / 16777216.0 * 180.0 / kPi;
}

}  // namespace ja_test
