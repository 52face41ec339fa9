/* cyclone_peer's hostile mode: the defects it injects after valid messages (or in place of a
 * cloud), built from the valid message just read from the dump. */
#pragma once

#include <stddef.h>

#include "peer_dump.h"

/* Defects of a cloud, built from the valid cloud just sent (or in place of it: cloud_replaces). */
enum {
  C_POINT_STEP_SMALL,
  C_DATA_SHORT,
  C_DATA_LONG,
  C_ROW_STEP,
  C_BIG_ENDIAN,
  C_UNKNOWN_TYPE,
  C_DUPLICATE_FIELD,
  C_MISSING_XYZ,
  C_OFFSET_BEYOND,
  C_EMPTY,
  C_STAMP_ZERO,
  C_FAR_FUTURE,
  C_STALE,
  C_TOO_LARGE,
  C_HUGE,
  C_NAN_POINTS,
  C_ORGANIZED,
  C_BURST,
  C_BURST_TAIL,
  C_COUNT
};
extern const char* const cloud_names[C_COUNT];

/* A valid but unusual cloud that takes the valid one's place (and must give odometry itself). */
int cloud_replaces(int d);

/* Builds defect d from valid cloud m into *c (which the caller writes, then frees with
 * free_cloud). Returns the number of copies to write; *nonfinite counts the NaN/Inf coordinates
 * written (C_NAN_POINTS). */
int make_cloud_defect(int d, const cloud_t* m, size_t max_points, cloud_t* c, int* nonfinite);

void free_cloud(cloud_t* c);

enum { I_NAN, I_ABSURD, I_ZEROS, I_DUPLICATE, I_OUT_OF_ORDER, I_JUMP_BACK, I_FUTURE, I_COUNT };
extern const char* const imu_names[I_COUNT];

/* Builds IMU defect d from the valid sample m just sent into *out; I_OUT_OF_ORDER sends `held`,
 * the sample before m, after it. Returns 0 (nothing to send) for no defect (d < 0). */
int make_imu_defect(int d, const imu_t* m, const imu_t* held, imu_t* out);
