#include "sim/board_common/serial_line.hpp"

#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <pty.h>
#include <sys/ioctl.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include <cstdio>
#include <cstring>

#include "sim/board_common/options.hpp"

namespace ja {
namespace board {

uint64_t MonotonicNs() {
  timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<uint64_t>(ts.tv_sec) * 1000000000ull + static_cast<uint64_t>(ts.tv_nsec);
}

bool SerialFaults::Pass(uint64_t n, uint8_t* b) {
  if (drop_every_ && n % drop_every_ == 0) {
    ++dropped_;
    return false;
  }
  if (corrupt_every_ && n % corrupt_every_ == 0) {
    *b ^= 0x5A;
    ++corrupted_;
  }
  return true;
}

bool Pty::Open(const std::string& link) {
  char name[128];
  if (openpty(&master_, &slave_, name, nullptr, nullptr) != 0) {
    std::fprintf(stderr, "%s: openpty: %s\n", ProgramName(), std::strerror(errno));
    master_ = slave_ = -1;
    return false;
  }
  termios t;
  if (tcgetattr(slave_, &t) == 0) {
    cfmakeraw(&t);
    tcsetattr(slave_, TCSANOW, &t);
  }
  fcntl(master_, F_SETFL, fcntl(master_, F_GETFL) | O_NONBLOCK);
  fcntl(master_, F_SETFD, FD_CLOEXEC);
  fcntl(slave_, F_SETFD, FD_CLOEXEC);
  link_ = link;
  path_ = name;
  if (!link_.empty()) {
    const std::string tmp = link_ + ".tmp";
    unlink(tmp.c_str());
    if (symlink(name, tmp.c_str()) != 0 || rename(tmp.c_str(), link_.c_str()) != 0) {
      std::fprintf(stderr, "%s: cannot link %s: %s\n", ProgramName(), link_.c_str(),
                   std::strerror(errno));
    }
  }
  std::printf("PTY %s\n", name);
  std::fflush(stdout);
  return true;
}

void Pty::Close() {
  if (master_ >= 0) close(master_);
  if (slave_ >= 0) close(slave_);
  master_ = slave_ = -1;
  wire_.clear();
  path_.clear();
  if (!link_.empty()) unlink(link_.c_str());
}

int Pty::Unread() const {
  int n = 0;
  return (slave_ >= 0 && ioctl(slave_, FIONREAD, &n) == 0) ? n : 0;
}

void Pty::Receive(std::deque<uint8_t>* rx) {
  if (!open()) return;
  uint8_t buf[512];
  for (;;) {
    const ssize_t n = read(master_, buf, sizeof buf);
    if (n <= 0) break;
    rx->insert(rx->end(), buf, buf + n);
  }
}

void Pty::Flush() {
  if (wire_.empty()) return;
  if (!open()) {
    wire_.clear();
    return;
  }
  const ssize_t n = write(master_, wire_.data(), wire_.size());
  if (n > 0) wire_.erase(wire_.begin(), wire_.begin() + n);
}

void Pty::Wait(uint64_t ns) const {
  timespec ts{static_cast<time_t>(ns / 1000000000ull), static_cast<long>(ns % 1000000000ull)};
  if (open()) {
    pollfd p{master_, static_cast<short>(POLLIN | (wire_.empty() ? 0 : POLLOUT)), 0};
    ppoll(&p, 1, &ts, nullptr);
  } else {
    nanosleep(&ts, nullptr);
  }
}

UartLine::UartLine(Pty& pty, const CommonOptions& o)
    : pty_(pty), faults_(o.corrupt_every, o.drop_every) {}

void UartLine::Transmit(uint8_t b, uint64_t now) {
  ++tx_bytes_;
  last_tx_ = now;
  if (cut_ready_) return;                          // the cable is being pulled
  if (cut_armed_ && b == 0x00) cut_ready_ = true;  // this delimiter ends the last whole frame
  if (!faults_.Pass(tx_bytes_, &b)) return;
  if (!pty_.open()) return;
  if (pty_.waiting() >= 2 * kWireMax) {
    ++bridge_dropped_;  // the host has not read for a long time (real time only)
    return;
  }
  pty_.Send(b);
}

void UartLine::ArmCut(uint64_t now, uint64_t idle) {
  if (cut_ready_) return;
  cut_armed_ = true;
  if (now - last_tx_ >= idle) cut_ready_ = true;
}

void Cable::Pull(const std::function<void()>& pump, const volatile sig_atomic_t* stop) {
  const uint64_t deadline = MonotonicNs() + 2000000000ull;
  uint64_t quiet = MonotonicNs();
  while (MonotonicNs() < deadline && !*stop) {
    pump();
    if (pty_.waiting() > 0 || pty_.Unread() > 0) quiet = MonotonicNs();
    if (MonotonicNs() - quiet > 100000000ull) break;
    usleep(2000);
  }
  std::printf("DISCONNECTED\n");
  std::fflush(stdout);
  pty_.Close();
  pulled_ = true;
  if (reconnect_after_s_ >= 0)
    reconnect_at_ns_ = MonotonicNs() + static_cast<uint64_t>(reconnect_after_s_ * 1e9);
}

bool Cable::Service() {
  if (reconnect_at_ns_ == 0 || MonotonicNs() < reconnect_at_ns_) return true;
  reconnect_at_ns_ = 0;
  return pty_.Open(link_);
}

}  // namespace board
}  // namespace ja
