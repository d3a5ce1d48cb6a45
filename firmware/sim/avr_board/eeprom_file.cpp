#include "sim/avr_board/eeprom_file.hpp"

#include <avr_eeprom.h>
#include <errno.h>
#include <fcntl.h>
#include <sim_avr.h>
#include <sim_cycle_timers.h>
#include <sim_io.h>
#include <unistd.h>

#include <cstring>

#include "sim/board_common/options.hpp"

namespace ja {
namespace avrboard {
namespace {

/// The application's EEPROM interface over a byte vector (SaveConfig writes the fresh image).
class MemoryEeprom final : public app::Eeprom {
 public:
  explicit MemoryEeprom(std::vector<uint8_t>& bytes) : bytes_(bytes) {}
  uint16_t Size() override { return static_cast<uint16_t>(bytes_.size()); }
  uint8_t Read(uint16_t addr) override { return addr < bytes_.size() ? bytes_[addr] : 0xFF; }
  void Write(uint16_t addr, uint8_t value) override {
    if (addr < bytes_.size()) bytes_[addr] = value;
  }

 private:
  std::vector<uint8_t>& bytes_;
};

constexpr uint16_t kEecr = 0x3F;  // data address (I/O 0x1F)
constexpr uint8_t kEepe = 1u << 1, kEempe = 1u << 2;
constexpr uint32_t kWriteUs = 3400;  // ATmega2560 datasheet: EEPROM programming time 3.4 ms

avr_cycle_count_t WriteDone(avr_t* avr, avr_cycle_count_t, void*) {
  avr->data[kEecr] &= static_cast<uint8_t>(~kEepe);
  return 0;
}

void OnEecrWrite(avr_t* avr, avr_io_addr_t, uint8_t v, void* param) {
  // Called after simavr's handler, which has written the byte (and cleared EEPE). A write
  // operation is EEPE written while EEMPE is armed: avr-libc's `sbi EECR, EEPE` right after
  // `sbi EECR, EEMPE` writes both bits.
  if ((v & kEepe) && (v & kEempe)) {
    avr->data[kEecr] |= kEepe;
    avr_cycle_timer_register_usec(avr, kWriteUs, WriteDone, nullptr);
    static_cast<EepromFile*>(param)->CountWrite();
  }
}

}  // namespace

void EepromFile::TimeWrites() { avr_register_io_write(avr_, kEecr, OnEecrWrite, this); }

EepromFile::~EepromFile() {
  if (fd_ >= 0) close(fd_);
  if (!tmpdir_.empty()) {
    unlink(path_.c_str());
    rmdir(tmpdir_.c_str());
  }
}

bool EepromFile::Open(const std::string& path, const app::Config& cfg, bool erased,
                      std::string* error) {
  path_ = path;
  if (path_.empty()) {
    tmpdir_ = board::MakeTempDir("ja-avr");
    if (tmpdir_.empty()) {
      *error = "cannot create a temporary directory";
      return false;
    }
    path_ = tmpdir_ + "/eeprom.bin";
  }
  fd_ = open(path_.c_str(), O_RDWR | O_CREAT, 0644);
  if (fd_ < 0) {
    *error = "cannot open the EEPROM file " + path_ + ": " + std::strerror(errno);
    return false;
  }
  if (!board::EepromFileFits(fd_, path_, kSize, error)) return false;
  saved_.assign(kSize, 0xFF);
  const ssize_t n = pread(fd_, saved_.data(), kSize, 0);
  if (n < 0) {
    *error = "cannot read the EEPROM file " + path_ + ": " + std::strerror(errno);
    return false;
  }
  if (n == 0 && !erased) {
    MemoryEeprom mem(saved_);
    if (!app::SaveConfig(mem, cfg)) {
      *error = "cannot write the rig's configuration into the EEPROM image";
      return false;
    }
  } else if (n < kSize) {
    std::fill(saved_.begin() + n, saved_.end(), 0xFF);
  }
  if (pwrite(fd_, saved_.data(), kSize, 0) != kSize) {
    *error = "cannot write the EEPROM file " + path_ + ": " + std::strerror(errno);
    return false;
  }
  // simavr 1.6's EEPROM_SET refuses offset + size == the whole EEPROM (an off-by-one) and prints
  // on stdout; EEPROM_GET with a null buffer hands out the EEPROM's own bytes instead.
  avr_eeprom_desc_t d{nullptr, 0, 0};
  avr_ioctl(avr_, AVR_IOCTL_EEPROM_GET, &d);
  if (d.ee == nullptr) {
    *error = "the simulated MCU has no EEPROM";
    return false;
  }
  live_ = d.ee;
  std::memcpy(live_, saved_.data(), kSize);
  return true;
}

void EepromFile::Persist() {
  if (live_ == nullptr) return;
  const uint8_t* now = live_;
  for (uint16_t a = 0; a < kSize; ++a) {
    if (now[a] == saved_[a]) continue;
    uint16_t b = a;
    while (b < kSize && now[b] != saved_[b]) ++b;
    if (pwrite(fd_, now + a, b - a, a) != b - a) ok_ = false;
    std::memcpy(saved_.data() + a, now + a, b - a);
    a = b;
  }
}

}  // namespace avrboard
}  // namespace ja
