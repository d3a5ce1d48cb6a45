// The firmware drivers (firmware/drivers) against the virtual devices (firmware/sim/devices)
// through the DriverBusAdapter: what the drivers write must configure the models as intended,
// and what they read must decode to the motion fed in. Agreement here means drivers and
// models read the datasheets the same way.
#include <string.h>

#include "check.hpp"
#include "drivers/adxl345.hpp"
#include "drivers/adxl357.hpp"
#include "drivers/bno055.hpp"
#include "drivers/tca9548a.hpp"
#include "sim/devices/adxl345.hpp"
#include "sim/devices/adxl357.hpp"
#include "sim/devices/bno055.hpp"
#include "sim/devices/bus.hpp"
#include "sim/devices/i2c_bus_adapter.hpp"
#include "sim/devices/tca9548a.hpp"

namespace drv = ja::drivers;
namespace sim = ja::sim;
using drv::DeviceStatus;

namespace {

constexpr double kG = sim::kStandardGravity;
constexpr uint64_t kMs = 1000000;

/// The rig of a typical build: a mux with two identical ADXL345 (same address) on channels 0
/// and 1, an ADXL357 on 2 and a BNO055 on 3.
struct Rig {
  sim::ConstantMotion m0{0.5 * kG, -0.25 * kG, 1.0 * kG};
  sim::ConstantMotion m1{-0.75 * kG, 0.125 * kG, 0.9 * kG};
  sim::ConstantMotion m2{1.5 * kG, -0.3 * kG, 0.01 * kG};
  sim::ConstantMotion m3{1.23, -4.56, 9.81};
  sim::Bus bus;
  sim::Tca9548a mux{0x70};
  sim::Adxl345 a0{0x53, &m0};
  sim::Adxl345 a1{0x53, &m1};
  sim::Adxl357 c2{0x1D, &m2};
  sim::Bno055 b3{0x28, &m3};
  sim::DriverBusAdapter adapter{bus};
  sim::SimDelay delay{bus};
  drv::Tca9548a dmux{adapter, 0x70};
  drv::Tca9548aChannel ch0{dmux, 0}, ch1{dmux, 1}, ch2{dmux, 2}, ch3{dmux, 3};
  drv::Adxl345 d0{ch0, 0x53}, d1{ch1, 0x53};
  drv::Adxl357 d2{ch2, 0x1D};
  drv::Bno055 d3{ch3, delay, 0x28};

  Rig() {
    CHECK(bus.Attach(&mux));
    CHECK(bus.Attach(&a0, &mux, 0));
    CHECK(bus.Attach(&a1, &mux, 1));
    CHECK(bus.Attach(&c2, &mux, 2));
    CHECK(bus.Attach(&b3, &mux, 3));
  }
  void Advance(uint64_t ns) { bus.SetTimeNs(bus.time_ns() + ns); }
};

void TestConfigureAndRead() {
  Rig r;
  CHECK(r.d0.Configure() == DeviceStatus::kOk);
  CHECK(r.d1.Configure() == DeviceStatus::kOk);
  CHECK(r.d2.Configure() == DeviceStatus::kOk);
  CHECK(r.d3.Configure() == DeviceStatus::kOk);
  CHECK_EQ(r.a0.counters().config_violations + r.c2.counters().config_violations +
               r.b3.counters().config_violations,
           0u);
  CHECK_EQ(r.b3.counters().writes_ignored, 0u);
  // The drivers' settings as the models understood them.
  CHECK_EQ(r.a0.period_ns(), 1250000u);  // 800 Hz
  CHECK_EQ(r.a1.period_ns(), 1250000u);
  CHECK_EQ(r.c2.period_ns(), 1000000u);  // 1000 Hz
  CHECK_EQ(r.c2.lsb_per_g(), 51200.0);   // +-10 g
  CHECK_EQ(r.b3.active_mode(), sim::Bno055::kModeAccOnly);
  CHECK_EQ(r.b3.accel_period_ns(), 2000000u);  // 250 Hz bandwidth -> 500 Hz

  r.Advance(5 * kMs);
  drv::RawSample s;
  CHECK(r.d0.ReadSample(&s) == DeviceStatus::kOk);
  CHECK_NEAR(drv::CountsToMps2(s.x, drv::adxl345::kMps2PerCount), 0.5 * kG, 0.0039 * kG);
  CHECK_NEAR(drv::CountsToMps2(s.y, drv::adxl345::kMps2PerCount), -0.25 * kG, 0.0039 * kG);
  CHECK_NEAR(drv::CountsToMps2(s.z, drv::adxl345::kMps2PerCount), 1.0 * kG, 0.0039 * kG);
  CHECK(r.d0.ReadSample(&s) == DeviceStatus::kNotReady);  // no new conversion yet
  // Same address, other channel, other motion.
  CHECK(r.d1.ReadSample(&s) == DeviceStatus::kOk);
  CHECK_NEAR(drv::CountsToMps2(s.x, drv::adxl345::kMps2PerCount), -0.75 * kG, 0.0039 * kG);
  CHECK_NEAR(drv::CountsToMps2(s.y, drv::adxl345::kMps2PerCount), 0.125 * kG, 0.0039 * kG);
  CHECK(r.d2.ReadSample(&s) == DeviceStatus::kOk);
  const float g357 = drv::adxl357::GPerCount(drv::adxl357::Range::k10g);
  CHECK_NEAR(s.x * g357, 1.5, 1.0 / 51200);
  CHECK_NEAR(s.y * g357, -0.3, 1.0 / 51200);
  CHECK_NEAR(s.z * g357, 0.01, 1.0 / 51200);
  CHECK(r.d2.ReadSample(&s) == DeviceStatus::kNotReady);
  CHECK(r.d3.ReadSample(&s) == DeviceStatus::kOk);
  CHECK_EQ(s.x, 123);
  CHECK_EQ(s.y, -456);
  CHECK_EQ(s.z, 981);
  CHECK(r.d3.ReadSample(&s) == DeviceStatus::kNotReady);  // unchanged value

  // A 500 Hz loop for 1 s: the 800 Hz / 1000 Hz parts have a fresh sample in every frame.
  int fresh0 = 0, fresh2 = 0;
  for (int k = 0; k < 500; ++k) {
    r.Advance(2 * kMs);
    if (r.d0.ReadSample(&s) == DeviceStatus::kOk) ++fresh0;
    if (r.d2.ReadSample(&s) == DeviceStatus::kOk) ++fresh2;
  }
  CHECK_EQ(fresh0, 500);
  CHECK_EQ(fresh2, 500);
  // Alternating channels: every read pays one select (write + read-back) on the mux.
  CHECK(r.dmux.select_count() >= 1000u);
}

void TestBnoReconfigureNeedsTheWait() {
  // Reconfiguring a running BNO055: the driver's 20 ms wait after CONFIG is what lets its
  // ACC_Config write land (the model drops writes during the 19 ms switch).
  Rig r;
  CHECK(r.d3.Configure() == DeviceStatus::kOk);
  r.Advance(50 * kMs);
  drv::bno055::Settings s;
  s.range = drv::bno055::Range::k8g;
  CHECK(r.d3.Configure(s) == DeviceStatus::kOk);
  CHECK(r.b3.counters().writes_ignored == 0u);
  // The same sequence without waiting fails its read-back.
  struct NoDelay final : drv::Delay {
    void WaitMs(uint16_t) override {}
  } none;
  drv::Bno055 hasty(r.ch3, none, 0x28);
  s.range = drv::bno055::Range::k2g;
  CHECK(hasty.Configure(s) == DeviceStatus::kVerifyFailed);
  CHECK(r.b3.counters().writes_ignored > 0u);
}

void TestFaultsThroughDrivers() {
  {
    Rig r;
    r.a0.SetFault(sim::FaultKind::kNack, true);
    CHECK(r.d0.Configure() == DeviceStatus::kBusFault);
    CHECK(r.d1.Configure() == DeviceStatus::kOk);  // the neighbour is unaffected
  }
  {
    Rig r;
    r.a0.SetFault(sim::FaultKind::kWrongId, true);
    r.c2.SetFault(sim::FaultKind::kWrongId, true, 0xAD);  // DEVID_AD right, PARTID wrong too
    r.b3.SetFault(sim::FaultKind::kWrongId, true);
    CHECK(r.d0.Configure() == DeviceStatus::kWrongId);
    CHECK(r.d2.Configure() == DeviceStatus::kWrongId);
    CHECK(r.d3.Configure() == DeviceStatus::kWrongId);
  }
  {
    Rig r;
    r.mux.SetFault(sim::FaultKind::kWrongId, true);  // read-back mismatch
    CHECK(r.dmux.Select(0) == DeviceStatus::kVerifyFailed);
    CHECK(r.d0.Configure() == DeviceStatus::kBusFault);
    r.mux.SetFault(sim::FaultKind::kNack, true);
    CHECK(r.dmux.Select(1) == DeviceStatus::kBusFault);
  }
  {
    Rig r;
    CHECK(r.d0.Configure() == DeviceStatus::kOk);
    CHECK(r.d2.Configure() == DeviceStatus::kOk);
    r.a0.SetFault(sim::FaultKind::kSaturate, true);
    r.c2.SetFault(sim::FaultKind::kSaturate, true);
    r.Advance(5 * kMs);
    drv::RawSample s;
    CHECK(r.d0.ReadSample(&s) == DeviceStatus::kOk);
    CHECK(s.x == 511 && s.y == -512 && s.z == 511);  // full-res +-2 g: 10 bits
    CHECK(r.d2.ReadSample(&s) == DeviceStatus::kOk);
    CHECK(s.x == 524287 && s.y == -524288);
    // Frozen, conversions stopped: the driver sees no data-ready.
    r.a0.SetFault(sim::FaultKind::kFrozen, true, 1);
    r.Advance(5 * kMs);
    CHECK(r.d0.ReadSample(&s) == DeviceStatus::kNotReady);
    // Frozen values with data-ready: fresh by the flag, stuck in value.
    r.a0.ClearFaults();
    r.a0.SetFault(sim::FaultKind::kFrozen, true, 0);
    r.Advance(5 * kMs);
    drv::RawSample t;
    CHECK(r.d0.ReadSample(&s) == DeviceStatus::kOk);
    r.Advance(5 * kMs);
    CHECK(r.d0.ReadSample(&t) == DeviceStatus::kOk);
    CHECK(s.x == t.x && s.y == t.y && s.z == t.z);
    // NACK mid-run: a bus fault, and the others keep going.
    r.a0.SetFault(sim::FaultKind::kNack, true);
    r.Advance(5 * kMs);
    CHECK(r.d0.ReadSample(&s) == DeviceStatus::kBusFault);
    r.c2.ClearFaults();
    CHECK(r.d2.ReadSample(&s) == DeviceStatus::kOk);
  }
}

}  // namespace

int main() {
  TestConfigureAndRead();
  TestBnoReconfigureNeedsTheWait();
  TestFaultsThroughDrivers();
  return ja_test::Finish("test_sim_drivers");
}
