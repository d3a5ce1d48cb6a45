// USART0 of the simulated ATmega2560 <-> a pseudo-terminal, paced at the baud rate in simulated
// time, with the native board's serial faults (ja_native_board: --corrupt-every, --drop-every,
// disconnect and reconnect).
//
// Transmit: simavr raises UART_IRQ_OUTPUT when the firmware writes UDR0 and holds UDRE/TXC for
// `cycles_per_byte`, so the AVR itself paces what it sends. simavr 1.6 charges 11 bits per byte
// (it always counts a parity bit, SENSORS.md D2); the link sets `cycles_per_byte` to the 10 bits
// of 8N1 at the line rate: cycles = 10 * F_CPU / baud (500 000 baud: 320 cycles = 20 us). The
// line rate is the firmware's own (UBRR0, U2X0: baud = F_CPU / (8 (UBRR+1)) with U2X) unless
// --baud names another one (a deliberately slow line).
// Receive: the host's bytes enter UART_IRQ_INPUT one per byte time, while simavr's receive FIFO
// has room.
// Bytes the pty does not take wait in a bounded buffer; with --fast the board waits for the host
// (Blocked()), in real time what does not fit is dropped and counted (a USB bridge's full buffer).
#pragma once

#include <stdint.h>

#include <deque>
#include <string>
#include <vector>

struct avr_t;
struct avr_irq_t;
struct avr_uart_t;

namespace ja {
namespace avrboard {

struct LinkOptions {
  uint32_t baud = 0;  // 0: the firmware's rate
  uint64_t corrupt_every = 0, drop_every = 0;
  std::string link;      // symlink to the current pty
  std::string uart_log;  // every transmitted byte (before the faults), for benches
  bool pty = true;       // false: no pty (--no-pty: the log only)
};

class Pty {
 public:
  ~Pty() { Close(); }
  /// Opens a raw pty, keeps the slave open too (the host may close and reopen), prints
  /// "PTY <path>" on stdout.
  bool Open(const std::string& link);
  void Close();
  bool open() const { return master_ >= 0; }
  int master() const { return master_; }
  /// Bytes written to the master that the host has not read yet.
  int Unread() const;

 private:
  int master_ = -1, slave_ = -1;
  std::string link_;
};

class UartLink {
 public:
  static constexpr size_t kWireMax = 4096;

  UartLink(avr_t* avr, const LinkOptions& opt, Pty& pty);
  ~UartLink();
  /// Hooks USART0. False if the core has none.
  bool Attach();
  /// After every instruction batch: line rate, receive pacing, pty output.
  void Service();
  /// Reads what the host sent (non-blocking).
  void Receive();
  /// Bytes wait for the host (the pty is full).
  bool Blocked() const { return wire_.size() >= kWireMax; }
  bool Pending() const { return !wire_.empty(); }
  void Disconnected() { wire_.clear(), rx_.clear(), cut_armed_ = cut_ready_ = false; }
  /// The cable is to be pulled: at the end of the frame on the line (after its 0x00 delimiter,
  /// bytes after it no longer reach the wire), or at once when the line has been idle for
  /// `idle_cycles`. CutReady() tells when.
  void ArmCut(uint64_t idle_cycles);
  bool CutReady() const { return cut_ready_; }
  /// Writes what waits to the pty.
  void Flush();

  double baud() const { return baud_; }
  uint64_t tx_bytes() const { return tx_bytes_; }
  uint64_t rx_bytes() const { return rx_bytes_; }
  uint64_t bridge_dropped() const { return bridge_dropped_; }
  uint64_t dropped() const { return dropped_; }
  uint64_t corrupted() const { return corrupted_; }

 private:
  static void OnOutput(avr_irq_t* irq, uint32_t value, void* param);
  void Transmit(uint8_t b);
  void SetLineRate();

  avr_t* avr_;
  const LinkOptions& opt_;
  Pty& pty_;
  avr_uart_t* uart_ = nullptr;
  avr_irq_t* input_ = nullptr;
  uint64_t cycles_per_byte_ = 0;  // what the link set (10 bits per byte)
  uint64_t next_rx_ = 0;
  double baud_ = 0;
  std::vector<uint8_t> wire_;
  std::deque<uint8_t> rx_;
  FILE* log_ = nullptr;
  bool cut_armed_ = false, cut_ready_ = false;
  uint64_t last_tx_cycle_ = 0;
  uint64_t tx_bytes_ = 0, rx_bytes_ = 0, bridge_dropped_ = 0, dropped_ = 0, corrupted_ = 0;
};

}  // namespace avrboard
}  // namespace ja
