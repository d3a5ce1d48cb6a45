// The application on x86 over in-test fakes, start-up (APP.md "The loop": Start-up; "What a board
// implements"): the hello at boot and get_info decoded with the protocol's decoder, the inventory
// with each model's chip ID, a sensor on the bus itself (mux channel 255) beside or instead of
// the multiplexer's, a BNO055 waited for through its power-up boot.
#include <stdio.h>

#include <memory>

#include "app_test_helpers.hpp"
#include "check.hpp"

namespace {

namespace proto = ja::proto;
namespace ss = proto::sensor_status;
using ja::app::App;
using ja_test::Board;
using ja_test::kAdxl345;
using ja_test::kAdxl357;
using ja_test::kBno055;
using ja_test::MakeBoard;
using ja_test::MakeMixedBoard;
using ja_test::SetMixedSensors;
using ja_test::Stream;

/// set_sensor for an ADXL345 wired to the bus itself (no multiplexer channel).
proto::SetSensor DirectAdxl345(uint8_t slot, uint8_t count, uint8_t link, uint8_t address,
                               uint8_t range_g, int32_t x_um) {
  proto::SetSensor s = {};
  s.slot = slot;
  s.count = count;
  s.link = link;
  s.model = kAdxl345;
  s.mux_channel = ja::app::kNoMux;
  s.address = address;
  s.range_g = range_g;
  s.x = x_um;
  return s;
}

void TestHelloAtBoot() {
  auto b = MakeBoard();
  App app(b->hal);
  app.Begin();
  b->Flush();
  proto::Hello h;
  CHECK(b->Find(&h));
  CHECK_EQ(b->frames[0].header.msg_id, proto::Hello::kId);
  CHECK_EQ(b->frames[0].header.seq, 0);
  CHECK_EQ(h.protocol_version, proto::kProtocolVersion);
  CHECK_EQ(h.schema_hash, proto::kSchemaHash);
  CHECK_EQ(h.firmware_major, ja::app::kFirmwareMajor);
  CHECK_EQ(h.firmware_minor, ja::app::kFirmwareMinor);
  CHECK_EQ(h.board, static_cast<uint8_t>(proto::Board::kNative));
  CHECK_EQ(h.sample_rate_hz, 500);
  CHECK_EQ(h.eeprom, static_cast<uint8_t>(proto::EepromState::kEmptyDefaults));
  CHECK_EQ(h.sensors_count, 4);
  for (int i = 0; i < 4; ++i) {
    CHECK_EQ(h.sensors[i].model, kAdxl345);
    CHECK_EQ(h.sensors[i].chip_id, 0xE5);
    CHECK_EQ(h.sensors[i].mux_channel, i);
    CHECK_EQ(h.sensors[i].address, 0x53);
    CHECK_EQ(h.sensors[i].link, i < 2 ? 0 : 1);
    CHECK_EQ(h.sensors[i].status, 0);
  }
  CHECK_EQ(b->decoder.stats().crc_errors, 0u);
  CHECK_EQ(b->decoder.stats().malformed, 0u);

  // get_info: a hello, then the ack.
  b->ClearFrames();
  const uint16_t seq = b->Command(proto::GetInfo());
  b->Run(app, 1000);
  CHECK_EQ(b->frame_count, 2);
  CHECK_EQ(b->frames[0].header.msg_id, proto::Hello::kId);
  CHECK_EQ(b->AckError(proto::GetInfo::kId, seq), 0);
}

void TestInventoryReadsChipIds() {
  auto b = MakeMixedBoard();
  App app(b->hal);
  app.Begin();
  uint16_t q[2];
  SetMixedSensors(*b, q);
  b->Run(app, 100000);
  CHECK_EQ(b->AckError(proto::SetSensor::kId, q[0]), 0);
  CHECK_EQ(b->AckError(proto::SetSensor::kId, q[1]), 0);
  b->ClearFrames();
  b->Command(proto::GetInfo());
  b->Run(app, 1000);
  proto::Hello h;
  CHECK(b->Find(&h));
  CHECK_EQ(h.sensors[1].model, kAdxl357);
  CHECK_EQ(h.sensors[1].chip_id, 0xED);
  CHECK_EQ(h.sensors[1].range_g, 10);
  CHECK_EQ(h.sensors[3].model, kBno055);
  CHECK_EQ(h.sensors[3].chip_id, 0xA0);
  for (int i = 0; i < 4; ++i) CHECK_EQ(h.sensors[i].status, 0);
  // The ADXL357 was configured for +-10 g and a 1 kHz ODR (>= 1.6 x 500 Hz); the BNO055 is in
  // ACCONLY after the datasheet's mode-switch waits.
  CHECK_EQ(b->bus.chips[1].regs[0x2C] & 3, 1);
  CHECK_EQ(b->bus.chips[1].regs[0x28] & 0xF, 2);
  CHECK_EQ(b->bus.chips[3].regs[0x3D], 0x01);
  CHECK(b->delay.total_ms >= 28);
  // All four stream with fresh samples (the BNO055's value changes every read here).
  b->ClearFrames();
  b->Command(Stream(proto::stream_mode::kSampleEstimate));
  b->Run(app, 100000);
  proto::SampleEstimate m;
  CHECK(b->Last(&m));
  CHECK_EQ(m.sensors_count, 4);
  for (int i = 0; i < 4; ++i) {
    CHECK_EQ(m.sensors[i].fresh, 1);
    CHECK_EQ(m.sensors[i].status, 0);
  }
}

void TestSensorOnRootBus() {
  // mux_channel 255: the sensor is reached without the multiplexer (here the multiplexer NACKs
  // throughout: only that sensor works; switching every channel off before its reads NACKs too,
  // which counts as no channel on).
  std::unique_ptr<Board> b(new Board());
  b->bus.Add(kAdxl345, 0x1D, -1);
  b->bus.mux_nack = true;
  App app(b->hal);
  app.Begin();
  const uint16_t q = b->Command(DirectAdxl345(0, 4, 0, 0x1D, 2, 47500));
  b->Command(Stream(proto::stream_mode::kSampleEstimate));
  b->Run(app, 100000);
  CHECK_EQ(b->AckError(proto::SetSensor::kId, q), 0);
  proto::SampleEstimate m;
  CHECK(b->Last(&m));
  CHECK_EQ(m.sensors[0].status, 0);
  CHECK_EQ(m.sensors[0].fresh, 1);
  for (int i = 1; i < 4; ++i) CHECK(m.sensors[i].status & ss::kNack);
  CHECK_EQ(b->bus.chips[0].regs[0x31], 0x08);  // full resolution, +-2 g
}

/// A sensor on the bus itself at the address of the parts behind the multiplexer: every channel
/// is switched off before it is read, so the direct part answers, not the channel's (with the
/// last channel left on, the muxed part answered every read of the direct slot).
void TestDirectSensorBesideMuxedOnesOfItsAddress() {
  std::unique_ptr<Board> b(new Board());
  b->AddDefaultChips();  // 0x53 on channels 0-3
  ja_test::FakeChip& direct = b->bus.Add(kAdxl345, 0x53, -1);
  for (int i = 0; i < 4; ++i) b->bus.chips[i].force_mps2[0] = 1.0f;
  direct.force_mps2[0] = -5.0f;
  App app(b->hal);
  app.Begin();
  const uint16_t q = b->Command(DirectAdxl345(4, 5, 1, 0x53, 4, 100000));
  b->Run(app, 200000);
  CHECK_EQ(b->AckError(proto::SetSensor::kId, q), 0);
  fprintf(stderr, "direct 0x53 beside muxed 0x53: counts.x %d (direct part -5 m/s^2), muxed %d\n",
          static_cast<int>(app.sensor(4).counts().x), static_cast<int>(app.sensor(0).counts().x));
  CHECK_EQ(app.sensor(4).status() & (ss::kNack | ss::kWrongId | ss::kNotConfigured), 0);
  CHECK(app.sensor(4).counts().x < -100);                            // -5 m/s^2 = -131 counts
  for (int i = 0; i < 4; ++i) CHECK(app.sensor(i).counts().x > 20);  // +1 m/s^2 = 26
}

void TestBnoBootWait() {
  // A BNO055 NACKs for its ~650 ms power-up boot: Begin keeps probing before the hello; a part
  // that never answers costs the 700 ms once and is reported.
  std::unique_ptr<Board> b(new Board());
  b->bus.Add(kAdxl345, 0x53, 0);
  ja_test::FakeChip& bno = b->bus.Add(kBno055, 0x28, 1);
  bno.nack_next = 1000000;  // silent until released below
  // Configure slot 1 as a BNO055 in EEPROM (the app reads its rig from there at boot).
  ja::app::Config c;
  ja::app::SetDefaults(c);
  c.sensor_count = 2;
  c.sensors[1].model = kBno055;
  c.sensors[1].address = 0x28;
  c.sensors[1].mux_channel = 1;
  CHECK(ja::app::SaveConfig(b->eeprom, c));
  struct Releaser final : ja::drivers::Delay {
    ja_test::FakeClock* clock;
    ja_test::FakeChip* chip;
    uint32_t total_ms = 0;
    void WaitMs(uint16_t ms) override {
      clock->now_us += 1000u * ms;
      total_ms += ms;
      if (total_ms >= 600) chip->nack_next = 0;  // booted
    }
  } releaser;
  releaser.clock = &b->clock;
  releaser.chip = &bno;
  ja::app::Hal hal{b->bus, releaser, b->clock, b->serial, b->eeprom, b->system, 2};
  App app(hal);
  app.Begin();
  b->Flush();
  proto::Hello h;
  CHECK(b->Find(&h));
  CHECK_EQ(h.sensors[1].chip_id, 0xA0);
  CHECK_EQ(h.sensors[1].status, 0);
  CHECK(releaser.total_ms >= 600 && releaser.total_ms <= 700);
  // Never answers: 700 ms, then NACK in the hello.
  bno.nack_next = 1000000;
  releaser.total_ms = 0;
  releaser.chip = &b->bus.chips[15];  // release nothing
  b->ClearFrames();
  App again(hal);
  again.Begin();
  b->Flush();
  CHECK(b->Find(&h));
  CHECK(h.sensors[1].status & ss::kNack);
  CHECK_EQ(releaser.total_ms, 700u);
}

/// APP.md "Read times": with Hal::bus_byte_ns set, hello reports each sensor's read start after
/// the first (a read of 3 + 6 bytes per ADXL345 and a select of 2 before the next, behind its
/// own channel; an all-off write of 2 in front of a sensor on the bus itself) and the filter turns
/// the readings (it keeps the readings as read); with 0 (the default) every delay is 0 and it does
/// not.
void TestReadDelaysInHelloAndFilter() {
  for (const uint16_t byte_ns : {static_cast<uint16_t>(0), static_cast<uint16_t>(25000)}) {
    std::unique_ptr<Board> b(new Board());
    b->AddDefaultChips();
    b->bus.Add(kAdxl345, 0x1D, -1);
    for (int i = 0; i < 5; ++i) b->bus.chips[i].force_mps2[0] = 1.0f;
    b->hal.bus_byte_ns = byte_ns;
    App app(b->hal);
    app.Begin();
    const uint16_t q = b->Command(DirectAdxl345(4, 5, 1, 0x1D, 2, 100000));
    b->Command(Stream(proto::stream_mode::kSampleEstimate));
    b->Run(app, 200000);
    CHECK_EQ(b->AckError(proto::SetSensor::kId, q), 0);
    b->ClearFrames();
    b->Command(proto::GetInfo());
    b->Run(app, 5000);
    proto::Hello h;
    CHECK(b->Find(&h));
    CHECK_EQ(h.sensors_count, 5);
    const uint16_t unit = byte_ns / 1000u;  // us a byte
    for (int i = 0; i < 4; ++i) CHECK_EQ(h.sensors[i].read_delay_us, 11u * i * unit);
    CHECK_EQ(h.sensors[4].read_delay_us, 44u * unit);  // 4 reads, 3 selects and the all-off
    CHECK(app.filter_valid());
    // The readings are turned to their mean time (0.55 ms after slot 0's: slots 0..4 at 0,
    // 0.275, .., 1.1 ms): link b's second sensor (slot 3) has a lag, so its reading as read is
    // kept for the next step.
    const auto& st = app.filter_state();
    const bool kept = st.previous[1][2].raw() != 0 || st.previous[1][3].raw() != 0;
    CHECK_EQ(kept, byte_ns != 0);
  }
}

}  // namespace

int main() {
  TestHelloAtBoot();
  TestReadDelaysInHelloAndFilter();
  TestInventoryReadsChipIds();
  TestSensorOnRootBus();
  TestDirectSensorBesideMuxedOnesOfItsAddress();
  TestBnoBootWait();
  return ja_test::Finish("test_app_startup");
}
