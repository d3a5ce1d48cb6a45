#include "sim/avr_board/uart_link.hpp"

#include <avr_uart.h>
#include <errno.h>
#include <fcntl.h>
#include <pty.h>
#include <sim_avr.h>
#include <sim_io.h>
#include <sim_irq.h>
#include <sys/ioctl.h>
#include <termios.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstring>

namespace ja {
namespace avrboard {

bool Pty::Open(const std::string& link) {
  char name[128];
  if (openpty(&master_, &slave_, name, nullptr, nullptr) != 0) return false;
  termios t;
  if (tcgetattr(slave_, &t) == 0) {
    cfmakeraw(&t);
    tcsetattr(slave_, TCSANOW, &t);
  }
  fcntl(master_, F_SETFL, fcntl(master_, F_GETFL) | O_NONBLOCK);
  fcntl(master_, F_SETFD, FD_CLOEXEC);
  fcntl(slave_, F_SETFD, FD_CLOEXEC);
  link_ = link;
  if (!link_.empty()) {
    const std::string tmp = link_ + ".tmp";
    unlink(tmp.c_str());
    if (symlink(name, tmp.c_str()) != 0 || rename(tmp.c_str(), link_.c_str()) != 0) {
      std::fprintf(stderr, "ja_avr_board: cannot link %s: %s\n", link_.c_str(),
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
  if (!link_.empty()) unlink(link_.c_str());
}

int Pty::Unread() const {
  int n = 0;
  return (slave_ >= 0 && ioctl(slave_, FIONREAD, &n) == 0) ? n : 0;
}

UartLink::UartLink(avr_t* avr, const LinkOptions& opt, Pty& pty)
    : avr_(avr), opt_(opt), pty_(pty) {}

UartLink::~UartLink() {
  if (log_) std::fclose(log_);
}

bool UartLink::Attach() {
  const uint32_t ctl = AVR_IOCTL_UART_GETIRQ('0');
  for (avr_io_t* io = avr_->io_port; io; io = io->next) {
    if (io->irq_ioctl_get == ctl) uart_ = reinterpret_cast<avr_uart_t*>(io);
  }
  if (!uart_) return false;
  uint32_t flags = 0;  // no console echo, no usleep on status polls (SENSORS.md D2)
  avr_ioctl(avr_, AVR_IOCTL_UART_SET_FLAGS('0'), &flags);
  input_ = avr_io_getirq(avr_, ctl, UART_IRQ_INPUT);
  avr_irq_register_notify(avr_io_getirq(avr_, ctl, UART_IRQ_OUTPUT), OnOutput, this);
  if (!opt_.uart_log.empty()) {
    log_ = std::fopen(opt_.uart_log.c_str(), "wb");
    if (!log_) return false;
  }
  return true;
}

void UartLink::OnOutput(avr_irq_t*, uint32_t value, void* param) {
  static_cast<UartLink*>(param)->Transmit(static_cast<uint8_t>(value));
}

void UartLink::ArmCut(uint64_t idle_cycles) {
  if (cut_ready_) return;
  cut_armed_ = true;
  if (avr_->cycle - last_tx_cycle_ >= idle_cycles) cut_ready_ = true;
}

void UartLink::Transmit(uint8_t b) {
  ++tx_bytes_;
  last_tx_cycle_ = avr_->cycle;
  if (log_) std::fputc(b, log_);
  if (cut_ready_) return;                          // the cable is being pulled
  if (cut_armed_ && b == 0x00) cut_ready_ = true;  // this delimiter ends the last whole frame
  if (opt_.drop_every && tx_bytes_ % opt_.drop_every == 0) {
    ++dropped_;
    return;
  }
  if (opt_.corrupt_every && tx_bytes_ % opt_.corrupt_every == 0) {
    b ^= 0x5A;
    ++corrupted_;
  }
  if (!opt_.pty || !pty_.open()) return;
  if (wire_.size() >= 2 * kWireMax) {
    ++bridge_dropped_;  // the host has not read for a long time (real time only)
    return;
  }
  wire_.push_back(b);
}

void UartLink::SetLineRate() {
  // simavr: cycles_per_byte = 11 * cycles_per_bit, cycles_per_bit = (UBRR+1) * 8 (U2X) or * 16.
  // The firmware's rate: baud = 11 * F_CPU / cycles_per_byte. 8N1 on the line: 10 bits per byte.
  if (!uart_->cycles_per_byte || uart_->cycles_per_byte == cycles_per_byte_) return;
  const double fw_baud = 11.0 * avr_->frequency / double(uart_->cycles_per_byte);
  baud_ = opt_.baud ? double(opt_.baud) : fw_baud;
  if (opt_.baud && std::fabs(fw_baud / opt_.baud - 1.0) > 0.03) {
    std::fprintf(stderr,
                 "ja_avr_board: the firmware set USART0 to %.0f baud; the line runs at --baud "
                 "%u\n",
                 fw_baud, opt_.baud);
  }
  cycles_per_byte_ = static_cast<uint64_t>(std::llround(10.0 * avr_->frequency / baud_));
  uart_->cycles_per_byte = cycles_per_byte_;
}

void UartLink::Service() {
  SetLineRate();
  if (!rx_.empty() && cycles_per_byte_ && avr_->cycle >= next_rx_) {
    // Room in simavr's receive FIFO (64 entries, one always kept free)?
    const unsigned next_write = (uart_->input.write + 1u) & (uart_fifo_fifo_size - 1u);
    if (next_write != uart_->input.read) {
      avr_raise_irq(input_, rx_.front());
      rx_.pop_front();
      ++rx_bytes_;
      next_rx_ = avr_->cycle + cycles_per_byte_;
    }
  }
}

void UartLink::Receive() {
  if (!pty_.open()) return;
  uint8_t buf[512];
  for (;;) {
    const ssize_t n = read(pty_.master(), buf, sizeof buf);
    if (n <= 0) break;
    rx_.insert(rx_.end(), buf, buf + n);
  }
}

void UartLink::Flush() {
  if (wire_.empty()) return;
  if (!pty_.open()) {
    wire_.clear();
    return;
  }
  const ssize_t n = write(pty_.master(), wire_.data(), wire_.size());
  if (n > 0) wire_.erase(wire_.begin(), wire_.begin() + n);
}

}  // namespace avrboard
}  // namespace ja
