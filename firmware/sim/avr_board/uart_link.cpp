#include "sim/avr_board/uart_link.hpp"

#include <avr_uart.h>
#include <sim_avr.h>
#include <sim_io.h>
#include <sim_irq.h>

#include <cmath>
#include <cstdio>
#include <deque>

namespace ja {
namespace avrboard {

UartLink::UartLink(avr_t* avr, const board::CommonOptions& line, const LinkOptions& opt,
                   board::Pty& pty)
    : avr_(avr), line_baud_(line.baud), opt_(opt), line_(pty, line) {}

UartLink::~UartLink() {
  if (log_) std::fclose(log_);
}

bool UartLink::Attach() {
  const uint32_t ctl = AVR_IOCTL_UART_GETIRQ('0');
  for (avr_io_t* io = avr_->io_port; io; io = io->next) {
    if (io->irq_ioctl_get == ctl) uart_ = reinterpret_cast<avr_uart_t*>(io);
  }
  if (!uart_) return false;
  uint32_t flags = 0;  // no console echo, no usleep on status polls (docs/sensors.md §D2)
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

void UartLink::ArmCut(uint64_t idle_cycles) { line_.ArmCut(avr_->cycle, idle_cycles); }

void UartLink::Transmit(uint8_t b) {
  if (log_) std::fputc(b, log_);
  line_.Transmit(b, avr_->cycle);
}

void UartLink::SetLineRate() {
  // simavr: cycles_per_byte = 11 * cycles_per_bit, cycles_per_bit = (UBRR+1) * 8 (U2X) or * 16.
  // The firmware's rate: baud = 11 * F_CPU / cycles_per_byte. 8N1 on the line: 10 bits per byte.
  if (!uart_->cycles_per_byte || uart_->cycles_per_byte == cycles_per_byte_) return;
  const double fw_baud = 11.0 * avr_->frequency / double(uart_->cycles_per_byte);
  baud_ = line_baud_ ? double(line_baud_) : fw_baud;
  if (line_baud_ && std::fabs(fw_baud / line_baud_ - 1.0) > 0.03) {
    std::fprintf(stderr,
                 "ja_avr_board: the firmware set USART0 to %.0f baud; the line runs at --baud "
                 "%u\n",
                 fw_baud, line_baud_);
  }
  cycles_per_byte_ = static_cast<uint64_t>(std::llround(10.0 * avr_->frequency / baud_));
  uart_->cycles_per_byte = cycles_per_byte_;
}

void UartLink::Service() {
  SetLineRate();
  std::deque<uint8_t>& rx = line_.rx();
  if (!rx.empty() && cycles_per_byte_ && avr_->cycle >= next_rx_) {
    // Room in simavr's receive FIFO (64 entries, one always kept free)?
    const unsigned next_write = (uart_->input.write + 1u) & (uart_fifo_fifo_size - 1u);
    if (next_write != uart_->input.read) {
      avr_raise_irq(input_, rx.front());
      rx.pop_front();
      ++rx_bytes_;
      next_rx_ = avr_->cycle + cycles_per_byte_;
    }
  }
}

}  // namespace avrboard
}  // namespace ja
