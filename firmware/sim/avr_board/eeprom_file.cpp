#include "sim/avr_board/eeprom_file.hpp"

#include <avr_eeprom.h>
#include <sim_avr.h>
#include <sim_cycle_timers.h>
#include <sim_io.h>

#include <cstring>

namespace ja {
namespace avrboard {
namespace {

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

bool EepromFile::Open(const std::string& path, const app::Config& cfg, bool erased,
                      std::string* error) {
  if (!file_.Open(path, kSize, cfg, erased, "ja-avr", error)) return false;
  // simavr 1.6's EEPROM_SET refuses offset + size == the whole EEPROM (an off-by-one) and prints
  // on stdout; EEPROM_GET with a null buffer hands out the EEPROM's own bytes instead.
  avr_eeprom_desc_t d{nullptr, 0, 0};
  avr_ioctl(avr_, AVR_IOCTL_EEPROM_GET, &d);
  if (d.ee == nullptr) {
    *error = "the simulated MCU has no EEPROM";
    return false;
  }
  live_ = d.ee;
  std::memcpy(live_, file_.image().data(), kSize);
  return true;
}

void EepromFile::Persist() {
  if (live_ != nullptr) file_.Persist(live_);
}

}  // namespace avrboard
}  // namespace ja
