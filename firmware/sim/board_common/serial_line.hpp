// The virtual boards' serial line (ja_native_board, ja_avr_board, ja_sim_board.h's callers): a raw
// pseudo-terminal the host
// opens, the bytes on their way to it (the "wire"), the serial faults on the wire and the cable
// pulled and plugged back in. Launcher contract (host/jointangle/transport.py): `PTY <path>` on
// stdout (one flushed line) each time a pty opens, `DISCONNECTED` before it closes.
// Each board paces its bytes in its own simulated time and hands them to Pty::Send, or, where
// the board's UART hands out each byte as it sends it (the AVR board's USART0, a harness behind
// ja_sim_board.h), to UartLine::Transmit.
#pragma once

#include <signal.h>
#include <stddef.h>
#include <stdint.h>

#include <deque>
#include <functional>
#include <string>
#include <vector>

namespace ja {
namespace board {

struct CommonOptions;

/// --drop-every N / --corrupt-every M: the nth byte on the wire (n counted from 1) is dropped
/// when N divides n, else XORed with 0x5A when M divides n (0: never).
class SerialFaults {
 public:
  SerialFaults(uint64_t corrupt_every, uint64_t drop_every)
      : corrupt_every_(corrupt_every), drop_every_(drop_every) {}
  /// False: byte n is dropped; else *b as it goes on the wire.
  bool Pass(uint64_t n, uint8_t* b);
  uint64_t dropped() const { return dropped_; }
  uint64_t corrupted() const { return corrupted_; }

 private:
  uint64_t corrupt_every_, drop_every_;
  uint64_t dropped_ = 0, corrupted_ = 0;
};

/// The pseudo-terminal: raw, the master non-blocking; the board keeps the slave open too so the
/// host can close and reopen it without the master seeing a hang-up.
class Pty {
 public:
  ~Pty() { Close(); }
  /// Opens a pty, points the symlink `link` (if any) at it, prints "PTY <path>" on stdout.
  /// False after a message on stderr.
  bool Open(const std::string& link);
  /// Closes it (what still waits on the wire is lost) and removes the symlink.
  void Close();
  bool open() const { return master_ >= 0; }
  int master() const { return master_; }
  /// The open pty's path ("" when closed).
  const std::string& path() const { return path_; }
  /// Bytes written to the master that the host has not read yet.
  int Unread() const;
  /// Appends what the host sent to *rx (non-blocking).
  void Receive(std::deque<uint8_t>* rx);
  /// Puts a byte on the wire (lost while the pty is closed).
  void Send(uint8_t b) {
    if (open()) wire_.push_back(b);
  }
  /// Bytes on the wire the pty has not taken yet.
  size_t waiting() const { return wire_.size(); }
  /// Writes what waits on the wire to the pty, as much as it takes.
  void Flush();
  /// Sleeps up to `ns` (real time); a byte from the host, or room in the pty while bytes wait
  /// on the wire, ends the wait early.
  void Wait(uint64_t ns) const;

 private:
  int master_ = -1, slave_ = -1;
  std::string link_, path_;
  std::vector<uint8_t> wire_;
};

/// --disconnect-after / --reconnect-after: the cable pulled, and a new pty some wall time later.
class Cable {
 public:
  Cable(Pty& pty, const std::string& link, double reconnect_after_s)
      : pty_(pty), link_(link), reconnect_after_s_(reconnect_after_s) {}
  /// Lets the host read what was sent (pump() moves due bytes to the pty; until the wire and the
  /// pty have been empty for 100 ms, at most 2 s or until *stop), then prints `DISCONNECTED`
  /// and closes the pty: said before the pty goes, so a host that sees the hang-up finds the line
  /// and does not reopen the old /dev/pts/N, which the system may give to another process.
  void Pull(const std::function<void()>& pump, const volatile sig_atomic_t* stop);
  bool pulled() const { return pulled_; }
  /// Opens the new pty when it is due; false when that fails.
  bool Service();

 private:
  Pty& pty_;
  std::string link_;
  double reconnect_after_s_;
  bool pulled_ = false;
  uint64_t reconnect_at_ns_ = 0;  // monotonic, 0: none
};

/// The board UART's end of the line, for a board whose UART hands out each byte as it sends it
/// (it paces them itself): each byte passes the serial faults onto the pty's wire, what the host
/// sends waits in rx() until the UART takes it, and the cable is cut between frames. `now` is
/// the board's simulated time in whatever unit it counts (AVR cycles, ns), the same in every call.
/// Bytes the pty does not take wait on its wire: Blocked() at kWireMax (a board running --fast
/// waits for the host then); at 2 kWireMax (real time: a host that has not read for a long time)
/// further bytes are dropped and counted, as a USB bridge's full buffer does.
class UartLine {
 public:
  static constexpr size_t kWireMax = 4096;

  UartLine(Pty& pty, const CommonOptions& o);
  /// A byte the UART sent at `now`: counted (from 1: the serial faults' n), then, unless the cut
  /// is ready, through the serial faults onto the wire (lost while the pty is closed).
  void Transmit(uint8_t b, uint64_t now);
  /// The cable is to be pulled: at the end of the frame on the line (after its 0x00 delimiter;
  /// bytes after it no longer reach the wire), or at once when nothing was sent for `idle` (the
  /// line is between frames). CutReady() tells when. Called again while armed, it checks the
  /// idle time again.
  void ArmCut(uint64_t now, uint64_t idle);
  bool CutReady() const { return cut_ready_; }
  /// The cable is out: what the host sent and the UART has not taken is lost, the cut disarmed.
  void Disconnected() {
    rx_.clear();
    cut_armed_ = cut_ready_ = false;
  }
  /// Reads what the host sent into rx() (non-blocking).
  void Receive() { pty_.Receive(&rx_); }
  /// The host's bytes the UART has not taken yet (it pops them at its own pace).
  std::deque<uint8_t>& rx() { return rx_; }
  /// Bytes wait for the host (the pty is full).
  bool Blocked() const { return pty_.waiting() >= kWireMax; }
  /// Writes what waits on the wire to the pty.
  void Flush() { pty_.Flush(); }

  uint64_t tx_bytes() const { return tx_bytes_; }
  uint64_t bridge_dropped() const { return bridge_dropped_; }
  uint64_t dropped() const { return faults_.dropped(); }
  uint64_t corrupted() const { return faults_.corrupted(); }

 private:
  Pty& pty_;
  SerialFaults faults_;
  std::deque<uint8_t> rx_;
  bool cut_armed_ = false, cut_ready_ = false;
  uint64_t last_tx_ = 0;
  uint64_t tx_bytes_ = 0, bridge_dropped_ = 0;
};

/// CLOCK_MONOTONIC in ns.
uint64_t MonotonicNs();

}  // namespace board
}  // namespace ja
