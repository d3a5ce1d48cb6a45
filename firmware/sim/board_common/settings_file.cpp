#include "sim/board_common/settings_file.hpp"

#include <errno.h>
#include <fcntl.h>
#include <sys/types.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>

#include "sim/board_common/options.hpp"

namespace ja {
namespace board {
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

}  // namespace

SettingsFile::~SettingsFile() {
  if (fd_ >= 0) close(fd_);
  if (!tmpdir_.empty()) {
    unlink(path_.c_str());
    rmdir(tmpdir_.c_str());
  }
}

bool SettingsFile::Open(const std::string& path, uint32_t size, const app::Config& cfg, bool erased,
                        const char* tmp_prefix, std::string* error) {
  if (fd_ >= 0 || !tmpdir_.empty()) {
    *error = "the settings file " + path_ + " is open already";
    return false;
  }
  if (size == 0 || size > 0xFFFF) {
    *error = "a settings store of " + std::to_string(size) + " bytes (1..65535)";
    return false;
  }
  path_ = path;
  if (path_.empty()) {
    tmpdir_ = MakeTempDir(tmp_prefix);
    if (tmpdir_.empty()) {
      *error = "cannot create a temporary directory";
      return false;
    }
    path_ = tmpdir_ + "/eeprom.bin";
  }
  fd_ = open(path_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd_ < 0) {
    *error = "cannot open the EEPROM file " + path_ + ": " + std::strerror(errno);
    return false;
  }
  if (!EepromFileFits(fd_, path_, size, error)) return false;
  saved_.assign(size, 0xFF);
  const ssize_t n = pread(fd_, saved_.data(), size, 0);
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
  } else if (n < static_cast<ssize_t>(size)) {
    std::fill(saved_.begin() + n, saved_.end(), 0xFF);
  }
  if (pwrite(fd_, saved_.data(), size, 0) != static_cast<ssize_t>(size)) {
    *error = "cannot write the EEPROM file " + path_ + ": " + std::strerror(errno);
    return false;
  }
  return true;
}

uint32_t SettingsFile::Persist(const uint8_t* now) {
  const uint32_t size = static_cast<uint32_t>(saved_.size());
  uint32_t changed = 0;
  for (uint32_t a = 0; a < size; ++a) {
    if (now[a] == saved_[a]) continue;
    uint32_t b = a;
    while (b < size && now[b] != saved_[b]) ++b;
    if (pwrite(fd_, now + a, b - a, a) != static_cast<ssize_t>(b - a)) ok_ = false;
    std::memcpy(saved_.data() + a, now + a, b - a);
    changed += b - a;
    a = b;
  }
  return changed;
}

}  // namespace board
}  // namespace ja
