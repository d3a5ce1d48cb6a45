// rig_reader: an Arduino Mega sketch that reads the virtual rig's parts through Wire the way
// common client code does, for `sim://avr?elf=` (issue 22 item 5; ../README.md "Your own
// sketch"). It is written for the datasheets, not for this project's firmware:
//
// - TCA9548A at 0x70: channel 0 holds an ADXL357 (0x1D) and an ADXL345 (0x53), channel 1 a
//   BNO055 (0x28) and an ADXL345 (0x53): rig.toml next to this file.
// - ADXL357: +-10 g, 125 Hz, FIFO watermark 30 entries; every report reads XDATA, then drains
//   the FIFO in 9-byte bursts at FIFO_DATA until the empty flag (x marker checked).
// - ADXL345: full resolution +-16 g, 100 Hz, stream mode with a watermark of 16; DATA_READY,
//   watermark, overrun and activity (> 1.5 g) in INT_SOURCE; every report drains the FIFO.
// - BNO055: waits for its boot (CHIP_ID), NDOF; Euler angles (heading, roll, pitch), quaternion,
//   gravity, linear acceleration, CALIB_STAT.
// - Wire's endTransmission() for an absent address (0x11): 2 on an ATmega2560, and for the
//   multiplexer: 0.
//
// Every 200 ms it prints one line per part (key=value, integers). A 'p' received on the serial
// line stops draining the FIFOs for one second (they overrun); the next reports show it.
#include <Arduino.h>
#include <Wire.h>

namespace {

constexpr uint8_t kMux = 0x70, kAdxl357 = 0x1D, kAdxl345 = 0x53, kBno055 = 0x28;
unsigned long g_pause_until = 0;
unsigned long g_adxl357_sets = 0, g_adxl345_sets = 0;  // drained since the start

void SelectChannel(uint8_t ch) {
  Wire.beginTransmission(kMux);
  Wire.write(static_cast<uint8_t>(1u << ch));
  Wire.endTransmission();
}

void WriteReg(uint8_t addr, uint8_t reg, uint8_t value) {
  Wire.beginTransmission(addr);
  Wire.write(reg);
  Wire.write(value);
  Wire.endTransmission();
}

// Register read: the pointer, a repeated START, n bytes.
uint8_t ReadRegs(uint8_t addr, uint8_t reg, uint8_t* out, uint8_t n) {
  Wire.beginTransmission(addr);
  Wire.write(reg);
  if (Wire.endTransmission(false) != 0) return 0;
  const uint8_t got = Wire.requestFrom(addr, n);
  for (uint8_t i = 0; i < got; ++i) out[i] = Wire.read();
  return got;
}

uint8_t ReadReg(uint8_t addr, uint8_t reg) {
  uint8_t v = 0;
  ReadRegs(addr, reg, &v, 1);
  return v;
}

long Adxl357Value(const uint8_t* b) {  // 20-bit two's complement, left-justified big-endian
  long v = (static_cast<long>(b[0]) << 12) | (static_cast<long>(b[1]) << 4) | (b[2] >> 4);
  if (v & 0x80000L) v -= 0x100000L;
  return v;
}

int Le16(const uint8_t* b) { return static_cast<int>(static_cast<uint16_t>(b[0] | (b[1] << 8))); }

void Print3(const char* key, long x, long y, long z) {
  Serial.print(' ');
  Serial.print(key);
  Serial.print('=');
  Serial.print(x);
  Serial.print(',');
  Serial.print(y);
  Serial.print(',');
  Serial.print(z);
}

void PrintHex(const char* key, uint8_t v) {
  Serial.print(' ');
  Serial.print(key);
  Serial.print('=');
  if (v < 0x10) Serial.print('0');
  Serial.print(v, HEX);
}

void PrintNum(const char* key, long v) {
  Serial.print(' ');
  Serial.print(key);
  Serial.print('=');
  Serial.print(v);
}

void SetUpChannel0() {
  SelectChannel(0);
  WriteReg(kAdxl357, 0x2D, 0x01);  // POWER_CTL: standby (configuration only there)
  WriteReg(kAdxl357, 0x2C, 0x81);  // RANGE: +-10 g
  WriteReg(kAdxl357, 0x28, 0x05);  // FILTER: 125 Hz, no high-pass
  WriteReg(kAdxl357, 0x29, 30);    // FIFO_SAMPLES: watermark
  WriteReg(kAdxl357, 0x2D, 0x00);  // measure
  WriteReg(kAdxl345, 0x2D, 0x00);  // standby
  WriteReg(kAdxl345, 0x31, 0x0B);  // DATA_FORMAT: full resolution, +-16 g
  WriteReg(kAdxl345, 0x2C, 0x0A);  // BW_RATE: 100 Hz
  WriteReg(kAdxl345, 0x24, 24);    // THRESH_ACT: 1.5 g
  WriteReg(kAdxl345, 0x27, 0x70);  // ACT_INACT_CTL: dc activity on x, y, z
  WriteReg(kAdxl345, 0x2F, 0x00);  // INT_MAP: all on INT1
  WriteReg(kAdxl345, 0x2E, 0x93);  // INT_ENABLE: DATA_READY, activity, watermark, overrun
  WriteReg(kAdxl345, 0x38, 0x00);  // FIFO_CTL: bypass (clears the FIFO) ...
  WriteReg(kAdxl345, 0x38, 0x90);  // ... then stream, watermark 16
  WriteReg(kAdxl345, 0x2D, 0x08);  // measure
}

unsigned long g_bno055_boot_ms = 0;  // how long the BNO055 took to answer after power-up

void SetUpChannel1() {
  SelectChannel(1);
  // A BNO055 answers ~650 ms after power-up: wait for its CHIP_ID as client libraries do.
  while (ReadReg(kBno055, 0x00) != 0xA0 && millis() < 2000) delay(10);
  g_bno055_boot_ms = millis();
  WriteReg(kBno055, 0x07, 0x00);  // PAGE_ID 0
  WriteReg(kBno055, 0x3D, 0x00);  // CONFIG
  delay(25);
  WriteReg(kBno055, 0x3B, 0x00);  // UNIT_SEL: m/s^2, degrees, Windows orientation
  WriteReg(kBno055, 0x3D, 0x0C);  // NDOF
  delay(20);
}

void ReportAdxl357(bool drain) {
  uint8_t b[9];
  const uint8_t id = ReadReg(kAdxl357, 0x02);
  const uint8_t status = ReadReg(kAdxl357, 0x04);
  const uint8_t entries = ReadReg(kAdxl357, 0x05);
  ReadRegs(kAdxl357, 0x08, b, 9);
  Serial.print(F("A357"));
  PrintHex("id", id);
  PrintHex("st", status);
  PrintNum("ent", entries);
  Print3("xyz", Adxl357Value(b), Adxl357Value(b + 3), Adxl357Value(b + 6));
  if (!drain) {
    Serial.println();
    return;
  }
  // Whole x-y-z sets, 9 bytes a burst at FIFO_DATA (the pointer stays there), until an entry
  // comes back with the empty flag; a set must start with the x marker.
  long first[3] = {0, 0, 0};
  uint8_t sets = 0, marks = 0, empty = 0;
  while (sets < 40) {
    if (ReadRegs(kAdxl357, 0x11, b, 9) != 9) break;
    if (b[2] & 0x02) {
      empty = 1;
      break;
    }
    if ((b[2] & 0x03) == 0x01 && (b[5] & 0x03) == 0 && (b[8] & 0x03) == 0) ++marks;
    if (sets == 0) {
      for (uint8_t k = 0; k < 3; ++k) first[k] = Adxl357Value(b + 3 * k);
    }
    ++sets;
  }
  g_adxl357_sets += sets;
  PrintNum("sets", sets);
  PrintNum("marked", marks);
  Print3("fifo", first[0], first[1], first[2]);
  PrintNum("empty", empty);
  PrintNum("total", static_cast<long>(g_adxl357_sets));
  Serial.println();
}

void ReportAdxl345(bool drain) {
  uint8_t b[6];
  const uint8_t source = ReadReg(kAdxl345, 0x30);
  const uint8_t fifo_status = ReadReg(kAdxl345, 0x39);
  Serial.print(F("A345"));
  PrintHex("id", ReadReg(kAdxl345, 0x00));
  PrintHex("src", source);
  PrintNum("ent", fifo_status & 0x3F);
  if (!drain) {
    Serial.println();
    return;
  }
  long first[3] = {0, 0, 0};
  const uint8_t n = fifo_status & 0x3F;
  for (uint8_t i = 0; i < n; ++i) {  // each 6-byte read pops one entry
    ReadRegs(kAdxl345, 0x32, b, 6);
    if (i == 0) {
      for (uint8_t k = 0; k < 3; ++k) first[k] = static_cast<int16_t>(Le16(b + 2 * k));
    }
  }
  g_adxl345_sets += n;
  Print3("fifo", first[0], first[1], first[2]);
  PrintNum("left", ReadReg(kAdxl345, 0x39) & 0x3F);
  PrintNum("total", static_cast<long>(g_adxl345_sets));
  Serial.println();
}

void ReportBno055() {
  uint8_t b[8];
  Serial.print(F("B055"));
  PrintHex("id", ReadReg(kBno055, 0x00));
  PrintHex("mode", ReadReg(kBno055, 0x3D));
  ReadRegs(kBno055, 0x1A, b, 6);  // EUL heading, roll, pitch: 16 LSB per degree
  Print3("eul", static_cast<int16_t>(Le16(b)), static_cast<int16_t>(Le16(b + 2)),
         static_cast<int16_t>(Le16(b + 4)));
  ReadRegs(kBno055, 0x20, b, 8);  // QUA w, x, y, z: 2^14 LSB per unit
  Serial.print(F(" qua="));
  for (uint8_t k = 0; k < 4; ++k) {
    if (k) Serial.print(',');
    Serial.print(static_cast<int16_t>(Le16(b + 2 * k)));
  }
  ReadRegs(kBno055, 0x2E, b, 6);  // GRV: 100 LSB per m/s^2
  Print3("grv", static_cast<int16_t>(Le16(b)), static_cast<int16_t>(Le16(b + 2)),
         static_cast<int16_t>(Le16(b + 4)));
  ReadRegs(kBno055, 0x28, b, 6);  // LIA
  Print3("lia", static_cast<int16_t>(Le16(b)), static_cast<int16_t>(Le16(b + 2)),
         static_cast<int16_t>(Le16(b + 4)));
  PrintHex("calib", ReadReg(kBno055, 0x35));
  PrintNum("boot", static_cast<long>(g_bno055_boot_ms));
  Serial.println();
}

void ReportWire() {
  Wire.beginTransmission(0x11);  // nobody there
  const uint8_t absent = Wire.endTransmission();
  Wire.beginTransmission(kMux);
  const uint8_t present = Wire.endTransmission();
  Serial.print(F("WIRE"));
  PrintNum("absent", absent);
  PrintNum("present", present);
  Serial.println();
}

}  // namespace

void setup() {
  Serial.begin(115200);
  Wire.begin();
  Wire.setClock(400000);
  SetUpChannel1();  // first: it waits for the BNO055's boot (the FIFOs would overrun meanwhile)
  SetUpChannel0();
}

void loop() {
  static unsigned long next = 0;
  while (Serial.available()) {
    if (Serial.read() == 'p') {
      g_pause_until = millis() + 1000;
      Serial.println(F("PAUSE"));
    }
  }
  if (static_cast<long>(millis() - next) < 0) return;
  next = millis() + 200;
  const bool drain = static_cast<long>(millis() - g_pause_until) >= 0;
  Serial.print(F("T ms="));
  Serial.println(millis());
  SelectChannel(0);
  ReportAdxl357(drain);
  ReportAdxl345(drain);
  SelectChannel(1);
  ReportBno055();
  ReportWire();
}
