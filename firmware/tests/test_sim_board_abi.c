/* libja_sim_board.so as a harness in another language uses it, from C: the header compiles as
 * C, the library links and exports the ABI (only the ABI: an internal symbol is hidden), and the
 * ja_sim* it hands out works with libja_sim_devices.so's calls (one library instance). The
 * behaviour of every call is tested in test_sim_board.cpp. */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "sim/board_common/ja_sim_board.h"

static int failures = 0;
#define CHECK(expr)                                                            \
  do {                                                                         \
    if (!(expr)) {                                                             \
      ++failures;                                                              \
      fprintf(stderr, "%s:%d: CHECK failed: %s\n", __FILE__, __LINE__, #expr); \
    }                                                                          \
  } while (0)

static void write_file(const char* path, const char* text) {
  FILE* f = fopen(path, "w");
  CHECK(f != NULL);
  if (f) {
    fputs(text, f);
    fclose(f);
  }
}

int main(void) {
  const char* base = getenv("TMPDIR");
  char dir[512], rig[600], motion[600], eeprom[600];
  snprintf(dir, sizeof dir, "%s/test_sim_board_abi-XXXXXX", base && *base ? base : "/tmp");
  CHECK(mkdtemp(dir) != NULL);
  snprintf(rig, sizeof rig, "%s/rig.toml", dir);
  snprintf(motion, sizeof motion, "%s/motion.csv", dir);
  snprintf(eeprom, sizeof eeprom, "%s/eeprom.bin", dir);
  write_file(rig,
             "sample_rate_hz = 100\n[links.a]\njoint = [0.3, 0.0]\n[[links.a.sensors]]\n"
             "model = \"adxl345\"\nposition = [0.1, 0.0]\nmux_channel = 0\naddress = 0x53\n"
             "range_g = 2\n[links.b]\njoint = [0.0, 0.0]\n[[links.b.sensors]]\n"
             "model = \"adxl345\"\nposition = [0.1, 0.0]\nmux_channel = 1\naddress = 0x53\n"
             "range_g = 2\n");
  write_file(motion,
             "t,a.0.x,a.0.y,a.0.z,b.0.x,b.0.y,b.0.z\n0,0,9.81,0,0,9.81,0\n1,0,9.81,0,0,9.81,0\n");

  CHECK(ja_sim_board_abi_version() == JA_SIM_BOARD_ABI_VERSION);
  /* The ABI is exported, the C++ inside is not. */
  CHECK(dlsym(RTLD_DEFAULT, "ja_sim_board_line_service") != NULL);
  CHECK(dlsym(RTLD_DEFAULT, "_ZN2ja5board11ProgramNameEv") == NULL);

  const char* argv[] = {"ja_abi_board", "--rig", rig, "--motion", motion, "--eeprom", eeprom};
  ja_sim_board* b = ja_sim_board_open(7, argv, NULL);
  CHECK(b != NULL);
  if (b == NULL) {
    fprintf(stderr, "%s\n", ja_sim_board_last_error(NULL));
    return 1;
  }
  /* The devices through libja_sim_devices.so: the mux and two ADXL345, DEVID behind channel 1. */
  ja_sim* sim = ja_sim_board_sim(b);
  CHECK(ja_sim_device_count(sim) == 3);
  const uint8_t mask = 0x02, reg = 0x00;
  uint8_t devid = 0;
  CHECK(ja_sim_i2c_write(sim, 0x70, &mask, 1) == JA_SIM_OK);
  CHECK(ja_sim_i2c_write_read(sim, 0x53, &reg, 1, &devid, 1) == JA_SIM_OK);
  CHECK(devid == 0xE5);
  CHECK(ja_sim_board_rate_hz(b) == 100);

  /* A new settings file: the app's image, magic "JA" (0x414A little-endian) first. */
  static uint8_t image[4096];
  CHECK(ja_sim_board_settings_open(b, image, sizeof image, 0) == JA_SIM_OK);
  CHECK(image[0] == 0x4A && image[1] == 0x41);
  CHECK(image[4095] == 0xFF);
  image[4095] = 0;
  CHECK(ja_sim_board_settings_write(b, image, sizeof image) == 1);

  /* A byte through the line to the host. */
  CHECK(ja_sim_board_line_open(b) == JA_SIM_OK);
  const int host = open(ja_sim_board_line_path(b), O_RDWR | O_NOCTTY);
  CHECK(host >= 0);
  CHECK(ja_sim_board_line_put(b, 0x7E, 1000) == 1);
  CHECK(ja_sim_board_line_flush(b) == JA_SIM_OK);
  uint8_t got = 0;
  CHECK(read(host, &got, 1) == 1 && got == 0x7E);
  ja_sim_board_line_counters c;
  CHECK(ja_sim_board_line_get_counters(b, &c, sizeof c) == JA_SIM_OK && c.tx_bytes == 1);
  close(host);
  ja_sim_board_close(b);

  /* The file kept what was written back. */
  FILE* f = fopen(eeprom, "rb");
  CHECK(f != NULL);
  if (f) {
    CHECK(fseek(f, 4095, SEEK_SET) == 0 && fgetc(f) == 0);
    fclose(f);
  }
  unlink(eeprom);
  unlink(rig);
  unlink(motion);
  rmdir(dir);
  if (failures) {
    fprintf(stderr, "test_sim_board_abi: %d check(s) failed\n", failures);
    return 1;
  }
  printf("test_sim_board_abi: all checks passed\n");
  return 0;
}
