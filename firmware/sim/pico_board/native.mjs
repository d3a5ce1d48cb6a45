// The C libraries the harness calls through koffi: libja_sim_devices (the virtual I2C devices,
// firmware/sim/devices/ja_sim_devices.h). Only the calls the harness makes are declared.
import koffi from 'koffi';

export const JA_SIM_ABI_VERSION = 2;

/** Binds libja_sim_devices.so at `path`; throws with the reason when it cannot. */
export function bindSimDevices(path) {
  const lib = koffi.load(path);
  const BusCounters = koffi.struct('ja_sim_bus_counters', {
    starts: 'uint64_t', repeated_starts: 'uint64_t', stops: 'uint64_t', address_acks: 'uint64_t',
    address_nacks: 'uint64_t', data_nacks: 'uint64_t', bytes_written: 'uint64_t',
    bytes_read: 'uint64_t', bus_errors: 'uint64_t', scl_bits: 'uint64_t',
  });
  const api = {
    abiVersion: lib.func('uint32_t ja_sim_abi_version()'),
    create: lib.func('void *ja_sim_create()'),
    lastError: lib.func('const char *ja_sim_last_error(void *sim)'),
    attachRig: lib.func('int ja_sim_attach_rig(void *sim, const char *spec)'),
    loadMotionCsv: lib.func('int ja_sim_load_motion_csv(void *sim, const char *path)'),
    setTimeNs: lib.func('int ja_sim_set_time_ns(void *sim, uint64_t t_ns)'),
    busStart: lib.func('int ja_sim_bus_start(void *sim)'),
    busWriteByte: lib.func('int ja_sim_bus_write_byte(void *sim, uint8_t byte)'),
    busReadByte: lib.func('int ja_sim_bus_read_byte(void *sim, int master_ack)'),
    busStop: lib.func('int ja_sim_bus_stop(void *sim)'),
    busCounters: lib.func('int ja_sim_get_bus_counters(void *sim, _Out_ ja_sim_bus_counters *out, size_t size)'),
    busCountersSize: koffi.sizeof(BusCounters),
  };
  const version = api.abiVersion();
  if (version !== JA_SIM_ABI_VERSION) {
    throw new Error(`${path}: ABI version ${version}, the harness speaks ${JA_SIM_ABI_VERSION} (rebuild)`);
  }
  return api;
}

export const JA_SIM_BOARD_ABI_VERSION = 1;
export const LINE_PULLED = 1;
export const LINE_RECONNECTED = 2;
export const WIRE_MAX = 4096;
export const SETTINGS_ERASED = 1;

/** Binds libja_sim_board.so (firmware/sim/board_common/ja_sim_board.h) at `path`. */
export function bindSimBoard(path) {
  const lib = koffi.load(path);
  const LineCounters = koffi.struct('ja_sim_board_line_counters', {
    tx_bytes: 'uint64_t', rx_bytes: 'uint64_t', dropped: 'uint64_t', corrupted: 'uint64_t',
    bridge_dropped: 'uint64_t', disconnects: 'uint64_t',
  });
  const api = {
    abiVersion: lib.func('uint32_t ja_sim_board_abi_version()'),
    open: lib.func('void *ja_sim_board_open(int argc, const char **argv, const char *usage)'),
    close: lib.func('void ja_sim_board_close(void *b)'),
    lastError: lib.func('const char *ja_sim_board_last_error(void *b)'),
    sim: lib.func('void *ja_sim_board_sim(void *b)'),
    baud: lib.func('uint32_t ja_sim_board_baud(void *b)'),
    fast: lib.func('int ja_sim_board_fast(void *b)'),
    disconnectAfterS: lib.func('double ja_sim_board_disconnect_after_s(void *b)'),
    settingsOpen: lib.func('int ja_sim_board_settings_open(void *b, _Inout_ uint8_t *image, size_t size, uint32_t flags)'),
    settingsWrite: lib.func('int ja_sim_board_settings_write(void *b, const uint8_t *image, size_t size)'),
    applyFaults: lib.func('int ja_sim_board_apply_faults(void *b, uint64_t t_ns)'),
    lineOpen: lib.func('int ja_sim_board_line_open(void *b)'),
    linePut: lib.func('int ja_sim_board_line_put(void *b, uint8_t byte, uint64_t t_ns)'),
    lineTake: lib.func('int ja_sim_board_line_take(void *b, _Out_ uint8_t *buf, size_t cap)'),
    lineFlush: lib.func('int ja_sim_board_line_flush(void *b)'),
    lineWaiting: lib.func('size_t ja_sim_board_line_waiting(void *b)'),
    lineWait: lib.func('int ja_sim_board_line_wait(void *b, uint64_t ns)'),
    lineService: lib.func('int ja_sim_board_line_service(void *b, uint64_t t_ns)'),
    lineConnected: lib.func('int ja_sim_board_line_connected(void *b)'),
    lineCounters: lib.func('int ja_sim_board_line_get_counters(void *b, _Out_ ja_sim_board_line_counters *out, size_t size)'),
    lineCountersSize: koffi.sizeof(LineCounters),
  };
  const version = api.abiVersion();
  if (version !== JA_SIM_BOARD_ABI_VERSION) {
    throw new Error(`${path}: ABI version ${version}, the harness speaks ${JA_SIM_BOARD_ABI_VERSION} (rebuild)`);
  }
  return api;
}
