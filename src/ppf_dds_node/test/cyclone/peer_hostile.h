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
  C_STALL,
  C_HEADER_NANOSEC,
  C_NO_FIELDS,
  C_OFFSET_BEYOND,
  C_EMPTY,
  C_STAMP_ZERO,
  C_FAR_FUTURE,
  C_STALE,
  C_TOO_LARGE,
  C_HUGE,
  C_NAN_POINTS,
  C_ORGANIZED,
  C_POINT_TIME_FUTURE,
  C_POINT_TIME_PAST,
  C_ROW_STEP_ZERO,
  C_MANY_FIELDS,
  C_LONG_FRAME_ID,
  C_BURST,
  C_BURST_TAIL,
  C_COUNT
};
extern const char* const cloud_names[C_COUNT];

/* A valid but unusual cloud that takes the valid one's place (and must give odometry itself). */
int cloud_replaces(int d);
/* A cloud that takes the valid one's place but must not give odometry (the next scan must). */
int cloud_replaces_unusable(int d);

/* C_STALL: this many valid clouds in a row are each replaced by a malformed copy (x as int8), so
 * scans keep arriving for 2 s while none can be processed. */
enum { kStallClouds = 20 };

/* Builds defect d from valid cloud m into *c (which the caller writes, then frees with
 * free_cloud). Returns the number of copies to write; *nonfinite counts the NaN/Inf coordinates
 * written (C_NAN_POINTS). */
int make_cloud_defect(int d, const cloud_t* m, size_t max_points, cloud_t* c, int* nonfinite);

void free_cloud(cloud_t* c);

enum {
  I_NAN,
  I_ABSURD,
  I_ZEROS,
  I_DUPLICATE,
  I_OUT_OF_ORDER,
  I_JUMP_BACK,
  I_FUTURE,
  I_HEADER_NANOSEC,
  I_CONFLICT,
  I_COUNT
};
/* I_CONFLICT: for this many samples, a copy with the same stamp and other values (+5 m/s^2,
 * +1 rad/s) goes out before each valid one. */
enum { kConflictSamples = 100 };
extern const char* const imu_names[I_COUNT];

/* Builds IMU defect d from the valid sample m just sent into *out; I_OUT_OF_ORDER sends `held`,
 * the sample before m, after it. Returns 0 (nothing to send) for no defect (d < 0). */
int make_imu_defect(int d, const imu_t* m, const imu_t* held, imu_t* out);
