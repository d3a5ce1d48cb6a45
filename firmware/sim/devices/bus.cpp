#include "sim/devices/bus.hpp"

namespace ja {
namespace sim {

int Bus::IndexOf(const I2cTarget* dev) const {
  for (int i = 0; i < count_; ++i) {
    if (entries_[i].dev == dev) return i;
  }
  return -1;
}

bool Bus::Attach(I2cTarget* dev, const Tca9548a* mux, uint8_t channel) {
  if (!dev || count_ >= kMaxDevices || IndexOf(dev) >= 0) return false;
  if (mux && (IndexOf(mux) < 0 || channel >= Tca9548a::kChannels)) return false;
  entries_[count_++] = Entry{dev, mux, channel};
  dev->AdvanceTo(now_ns_);
  return true;
}

bool Bus::Reachable(int i) const {
  // Walk up the mux chain; attachment order guarantees termination (parents come first).
  while (i >= 0 && i < count_) {
    const Entry& e = entries_[i];
    if (!e.mux) return true;
    if (!(e.mux->connected() & (1u << e.channel))) return false;
    i = IndexOf(e.mux);
  }
  return false;
}

bool Bus::SetTimeNs(uint64_t t_ns) {
  if (t_ns < now_ns_) return false;
  now_ns_ = t_ns;
  for (int i = 0; i < count_; ++i) entries_[i].dev->AdvanceTo(now_ns_);
  return true;
}

void Bus::Charge(uint32_t bits) {
  counters_.scl_bits += bits;
  if (!scl_hz_) return;
  // Exact: accumulate bits * 1e9 and carry whole nanoseconds.
  bit_rem_ += static_cast<uint64_t>(bits) * 1000000000u;
  const uint64_t ns = bit_rem_ / scl_hz_;
  bit_rem_ -= ns * scl_hz_;
  SetTimeNs(now_ns_ + ns);
}

void Bus::Start() {
  if (state_ == State::kIdle) {
    ++counters_.starts;
  } else {
    ++counters_.repeated_starts;
  }
  Charge(1);
  for (int i = 0; i < count_; ++i) {
    on_bus_[i] = Reachable(i);
    if (on_bus_[i]) entries_[i].dev->BusStart();
  }
  state_ = State::kAddress;
}

bool Bus::WriteByte(uint8_t byte) {
  Charge(9);
  switch (state_) {
    case State::kAddress: {
      const uint8_t addr7 = static_cast<uint8_t>(byte >> 1);
      const bool read = byte & 1u;
      bool ack = false;
      for (int i = 0; i < count_; ++i) {
        if (on_bus_[i] && entries_[i].dev->BusAddress(addr7, read)) ack = true;
      }
      if (ack) {
        ++counters_.address_acks;
        state_ = read ? State::kRead : State::kWrite;
      } else {
        ++counters_.address_nacks;
        state_ = State::kNacked;
      }
      return ack;
    }
    case State::kWrite: {
      ++counters_.bytes_written;
      bool ack = false;
      for (int i = 0; i < count_; ++i) {
        if (on_bus_[i] && entries_[i].dev->addressed() && entries_[i].dev->BusWrite(byte)) {
          ack = true;
        }
      }
      if (!ack) ++counters_.data_nacks;
      return ack;
    }
    default:
      ++counters_.bus_errors;
      return false;
  }
}

uint8_t Bus::ReadByte(bool ack) {
  Charge(9);
  if (state_ != State::kRead) {
    ++counters_.bus_errors;
    return 0xFF;
  }
  ++counters_.bytes_read;
  uint8_t v = 0xFF;  // open drain: released lines read high, drivers pull low
  for (int i = 0; i < count_; ++i) {
    if (on_bus_[i] && entries_[i].dev->addressed()) v &= entries_[i].dev->BusRead(ack);
  }
  return v;
}

void Bus::Stop() {
  if (state_ == State::kIdle) {
    ++counters_.bus_errors;
    return;
  }
  ++counters_.stops;
  Charge(1);
  state_ = State::kIdle;
  // Downstream devices first, multiplexers last: a new selection connects after this STOP.
  for (int i = count_ - 1; i >= 0; --i) {
    if (on_bus_[i]) entries_[i].dev->BusStop();
    on_bus_[i] = false;
  }
}

I2cResult Bus::Address(uint8_t addr7, bool read) {
  Start();
  return WriteByte(static_cast<uint8_t>((addr7 << 1) | (read ? 1u : 0u))) ? I2cResult::kOk
                                                                          : I2cResult::kAddressNack;
}

I2cResult Bus::Write(uint8_t addr7, const uint8_t* data, size_t n) {
  if (in_transaction()) return I2cResult::kBusError;
  I2cResult r = Address(addr7, false);
  for (size_t i = 0; r == I2cResult::kOk && i < n; ++i) {
    if (!WriteByte(data[i])) r = I2cResult::kDataNack;
  }
  Stop();
  return r;
}

I2cResult Bus::Read(uint8_t addr7, uint8_t* data, size_t n) {
  return WriteRead(addr7, nullptr, 0, data, n);
}

I2cResult Bus::WriteRead(uint8_t addr7, const uint8_t* w, size_t nw, uint8_t* r, size_t nr) {
  if (in_transaction()) return I2cResult::kBusError;
  I2cResult res = I2cResult::kOk;
  if (nw > 0) {
    res = Address(addr7, false);
    for (size_t i = 0; res == I2cResult::kOk && i < nw; ++i) {
      if (!WriteByte(w[i])) res = I2cResult::kDataNack;
    }
  }
  if (res == I2cResult::kOk && (nr > 0 || nw == 0)) {
    res = Address(addr7, true);  // repeated START when bytes were written
    for (size_t i = 0; res == I2cResult::kOk && i < nr; ++i) r[i] = ReadByte(i + 1 < nr);
  }
  Stop();
  return res;
}

}  // namespace sim
}  // namespace ja
