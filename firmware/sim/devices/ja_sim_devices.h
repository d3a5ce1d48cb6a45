/* C ABI over the virtual I2C bus and devices (firmware/sim/devices), for every simulated path:
 * the native virtual board, the simavr TWI bridge (simavr_twi.h) and the host's ctypes binding
 * (host/jointangle/boards/sim_devices.py). Opaque handle; devices are numbered 0.. in attach order.
 * Every function is safe on a NULL handle (it fails). Not thread-safe: one caller per handle. */
#ifndef JA_SIM_DEVICES_H
#define JA_SIM_DEVICES_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define JA_SIM_ABI_VERSION 2u /* 2: ja_sim_set_clock and the rig spec's clock= */

typedef struct ja_sim ja_sim;

/* Device models. */
enum { JA_SIM_ADXL345 = 1, JA_SIM_ADXL357 = 2, JA_SIM_BNO055 = 3, JA_SIM_TCA9548A = 4 };
/* Fault kinds (parameters: firmware/sim/devices/i2c_target.hpp FaultKind). */
enum {
  JA_SIM_FAULT_NACK = 1,
  JA_SIM_FAULT_WRONG_ID = 2,
  JA_SIM_FAULT_SATURATE = 3,
  JA_SIM_FAULT_FROZEN = 4
};
/* Transaction results (>= 0) and call errors (< 0). */
enum {
  JA_SIM_OK = 0,
  JA_SIM_ADDRESS_NACK = 1,
  JA_SIM_DATA_NACK = 2,
  JA_SIM_BUS_ERROR = 3,
  JA_SIM_EINVAL = -1
};

typedef struct ja_sim_device_counters {
  uint64_t transactions, address_nacks, bytes_written, bytes_read, samples, samples_read, overruns,
      writes_ignored, config_violations;
} ja_sim_device_counters;

typedef struct ja_sim_bus_counters {
  uint64_t starts, repeated_starts, stops, address_acks, address_nacks, data_nacks, bytes_written,
      bytes_read, bus_errors, scl_bits;
} ja_sim_bus_counters;

uint32_t ja_sim_abi_version(void);
ja_sim* ja_sim_create(void);
void ja_sim_destroy(ja_sim* sim);
/* Why the last failing call failed ("" if none). */
const char* ja_sim_last_error(const ja_sim* sim);

/* ---- Building the bus. ---- */
/* A TCA9548A at addr7 on the root bus (mux = -1) or behind channel `channel` of mux `mux`.
 * Returns the device number or JA_SIM_EINVAL. */
int ja_sim_add_mux(ja_sim* sim, uint8_t addr7, int mux, int channel);
/* A sensor (model JA_SIM_ADXL345/ADXL357/BNO055); motion_id names its CSV columns ("a.0"; NULL
 * or "" for none). Returns the device number or JA_SIM_EINVAL. */
int ja_sim_add_device(ja_sim* sim, int model, uint8_t addr7, int mux, int channel,
                      const char* motion_id);
/* Attaches a rig: one sensor per line, "<id> <model> <address> <mux_channel> [clock=<ppm>:<phase>]"
 * (e.g. "a.0 adxl345 0x53 0", "b.1 adxl357 0x1D 1 clock=-12000:0.25"; channel -1 = on the root
 * bus; clock= as ja_sim_set_clock), optional "mux <address>" (default 0x70, created when a
 * sensor sits behind it), '#' comments. Returns the number of sensors. */
int ja_sim_attach_rig(ja_sim* sim, const char* spec);
int ja_sim_device_count(const ja_sim* sim);
/* Any output pointer may be NULL. mux is -1 for the root bus. */
int ja_sim_device_info(const ja_sim* sim, int dev, int* model, int* addr7, int* mux, int* channel);
/* The device bound to motion_id, or JA_SIM_EINVAL. */
int ja_sim_find_device(const ja_sim* sim, const char* motion_id);
/* A sensor's own conversion clock (real parts run free on their own oscillators, so their grids
 * drift against each other and the board's loop): the oscillator's frequency error ppm (+ = fast,
 * |ppm| < 100000) and the grid's phase in [0, 1). For a nominal period P_nom (ns, what the
 * registers select) the part converts every P = floor(P_nom / (1 + ppm * 1e-6) + 0.5) ns at
 * device times O + j * P, j = 0, 1, ..., O = floor(phase * P + 0.5) (none before O); a BNO055's
 * accelerometer, gyroscope and fusion clocks all follow it. Default 0, 0 (the grid j * P_nom).
 * Used from the part's next start of conversions and at once by a running clock (restarted at
 * the current device time on the new grid). JA_SIM_EINVAL for a multiplexer, an unknown device
 * or values out of range. */
int ja_sim_set_clock(ja_sim* sim, int device, double ppm, double phase);

/* ---- Motion. ---- */
/* Loads an accelerations CSV; every device whose motion_id has columns is bound to them.
 * Returns the number of devices bound, or JA_SIM_EINVAL (see ja_sim_last_error). */
int ja_sim_load_motion_csv(ja_sim* sim, const char* path);
/* One sensor's series from arrays: t_s[rows] increasing, accel[rows*3] m/s^2, gyro[rows*3]
 * rad/s or NULL. Returns the number of devices that now have motion (all of them). */
int ja_sim_set_motion(ja_sim* sim, const char* motion_id, size_t rows, const double* t_s,
                      const double* accel, const double* gyro);
/* A constant reading for one device, replacing its series until the next motion load (static
 * poses); gyro may be NULL. */
int ja_sim_set_constant_motion(ja_sim* sim, int dev, const double accel[3], const double* gyro);
/* After the last row: 0 hold it (default), 1 wrap around. */
int ja_sim_set_motion_loop(ja_sim* sim, int loop);

/* ---- Time. ---- */
/* Device time moves forward to t (never back: an earlier t is ignored and returns 1). */
int ja_sim_set_time_us(ja_sim* sim, uint64_t t_us);
int ja_sim_set_time_ns(ja_sim* sim, uint64_t t_ns);
uint64_t ja_sim_time_ns(const ja_sim* sim);
/* 0 (default): bus transfers take no device time; else every SCL period at hz is charged. */
int ja_sim_set_scl_hz(ja_sim* sim, uint32_t hz);

/* ---- Byte level (simavr TWI): START/Sr, address or data byte -> ACK, read byte, STOP. ---- */
int ja_sim_bus_start(ja_sim* sim);
/* Returns 1 for ACK, 0 for NACK. The first byte after a START is (addr7 << 1) | R/W. */
int ja_sim_bus_write_byte(ja_sim* sim, uint8_t byte);
/* master_ack: 1 if the master will ACK this byte (more to come), 0 for the last one. */
int ja_sim_bus_read_byte(ja_sim* sim, int master_ack);
int ja_sim_bus_stop(ja_sim* sim);

/* ---- Whole transactions: JA_SIM_OK / ADDRESS_NACK / DATA_NACK / BUS_ERROR. ---- */
int ja_sim_i2c_write(ja_sim* sim, uint8_t addr7, const uint8_t* data, size_t n);
int ja_sim_i2c_read(ja_sim* sim, uint8_t addr7, uint8_t* data, size_t n);
/* Write, repeated START, read, STOP (a register read; smbus2 i2c_rdwr with two messages). */
int ja_sim_i2c_write_read(ja_sim* sim, uint8_t addr7, const uint8_t* w, size_t nw, uint8_t* r,
                          size_t nr);

/* ---- Faults and resets. ---- */
int ja_sim_inject_fault(ja_sim* sim, int dev, int kind, uint32_t param);
/* kind 0 clears every fault of the device. */
int ja_sim_clear_fault(ja_sim* sim, int dev, int kind);
/* Power cycle: power-up register values (BNO055 then boots for 650 ms). */
int ja_sim_power_cycle(ja_sim* sim, int dev);
/* BNO055: the Earth's magnetic field (uT; north, west, up) its magnetometer sees, and the part's
 * heading (degrees clockwise from north) when its fusion first aligns (absolute modes). */
int ja_sim_set_earth_field(ja_sim* sim, int dev, const double field_ut[3], double heading_deg);

/* ---- Counters (size = sizeof the struct the caller has: layout check). ---- */
int ja_sim_get_device_counters(const ja_sim* sim, int dev, ja_sim_device_counters* out,
                               size_t size);
int ja_sim_get_bus_counters(const ja_sim* sim, ja_sim_bus_counters* out, size_t size);

#ifdef __cplusplus
}
#endif

#endif /* JA_SIM_DEVICES_H */
