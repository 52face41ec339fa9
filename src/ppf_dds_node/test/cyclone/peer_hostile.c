/* cyclone_peer's defects (see peer_hostile.h). */
#include "peer_hostile.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* A copy the peer owns (field names, fields, data of data_bytes, zero-filled beyond the source). */
static cloud_t clone_cloud(const cloud_t* m, uint32_t data_bytes) {
  cloud_t c = *m;
  c.fields._buffer = (sensor_msgs_msg_dds__PointField_*)calloc(
      m->fields._length ? m->fields._length : 1, sizeof(sensor_msgs_msg_dds__PointField_));
  for (uint32_t i = 0; i < m->fields._length; ++i) {
    c.fields._buffer[i] = m->fields._buffer[i];
    c.fields._buffer[i].name = strdup(m->fields._buffer[i].name);
  }
  c.data._buffer = (uint8_t*)calloc(data_bytes ? data_bytes : 1, 1);
  memcpy(c.data._buffer, m->data._buffer,
         data_bytes < m->data._length ? data_bytes : m->data._length);
  c.data._length = c.data._maximum = data_bytes;
  return c;
}

void free_cloud(cloud_t* c) {
  for (uint32_t i = 0; i < c->fields._length; ++i) free(c->fields._buffer[i].name);
  free(c->fields._buffer);
  free(c->data._buffer);
}

static sensor_msgs_msg_dds__PointField_* find_field(cloud_t* c, const char* name) {
  for (uint32_t i = 0; i < c->fields._length; ++i)
    if (strcmp(c->fields._buffer[i].name, name) == 0) return &c->fields._buffer[i];
  return NULL;
}

/* The per-point time field of the simulated clouds (float32 seconds after the stamp), or NULL. */
static sensor_msgs_msg_dds__PointField_* find_time_field(cloud_t* c) {
  sensor_msgs_msg_dds__PointField_* t = find_field(c, "time");
  return t && t->datatype == 7 ? t : NULL; /* FLOAT32 */
}

const char* const cloud_names[C_COUNT] = {
    "point_step_small", "data_short",      "data_long",      "row_step",      "big_endian",
    "unknown_type",     "duplicate_field", "missing_xyz",    "stall",         "header_nanosec",
    "no_fields",        "offset_beyond",   "empty",          "stamp_zero",    "far_future",
    "stale",            "too_large",       "huge",           "nan_points",    "organized",
    "point_time_future", "point_time_past", "row_step_zero", "many_fields",   "long_frame_id",
    "burst",            "burst_tail"};
int cloud_replaces(int d) {
  return d == C_HUGE || d == C_NAN_POINTS || d == C_ORGANIZED || d == C_ROW_STEP_ZERO ||
         d == C_MANY_FIELDS || d == C_LONG_FRAME_ID || d == C_POINT_TIME_FUTURE;
}
int cloud_replaces_unusable(int d) { return d == C_POINT_TIME_PAST || d == C_STALL; }

const char* const imu_names[I_COUNT] = {"imu_nan",       "imu_absurd",        "imu_zeros",
                                        "imu_duplicate", "imu_out_of_order",  "imu_jump_back",
                                        "imu_future",    "imu_header_nanosec", "imu_conflict"};

/* Extra fields of C_MANY_FIELDS, and the length of C_LONG_FRAME_ID's frame_id. */
enum { kManyFields = 5000, kLongFrameId = 200000 };

int make_cloud_defect(int d, const cloud_t* m, size_t max_points, cloud_t* c, int* nonfinite) {
  const uint32_t n = m->width * m->height, step = m->point_step;
  switch (d) {
    case C_DATA_SHORT:
      *c = clone_cloud(m, m->data._length - 10 * step);
      return 1;
    case C_DATA_LONG:
      *c = clone_cloud(m, m->data._length + 64);
      return 1;
    case C_EMPTY:
      *c = clone_cloud(m, 0);
      c->width = 0;
      c->row_step = 0;
      return 1;
    case C_HUGE: {
      /* The same scan many times over: "several million points" of real geometry. */
      const uint32_t reps = (uint32_t)((max_points + n - 1) / n);
      *c = clone_cloud(m, m->data._length * reps);
      for (uint32_t r = 1; r < reps; ++r)
        memcpy(c->data._buffer + (size_t)r * m->data._length, m->data._buffer, m->data._length);
      c->width = n * reps;
      c->height = 1;
      c->row_step = c->width * step;
      return 1;
    }
    case C_MANY_FIELDS: {
      /* Valid: extra one-byte fields inside the point, each with its own name. */
      *c = clone_cloud(m, m->data._length);
      const uint32_t n0 = c->fields._length;
      c->fields._buffer = (sensor_msgs_msg_dds__PointField_*)realloc(
          c->fields._buffer, (n0 + kManyFields) * sizeof(sensor_msgs_msg_dds__PointField_));
      for (uint32_t i = 0; i < kManyFields; ++i) {
        char name[32];
        snprintf(name, sizeof(name), "extra_%u", i);
        sensor_msgs_msg_dds__PointField_* f = &c->fields._buffer[n0 + i];
        f->name = strdup(name);
        f->offset = i % step;
        f->datatype = 2; /* UINT8 */
        f->count = 1;
      }
      c->fields._length = c->fields._maximum = n0 + kManyFields;
      return 1;
    }
    case C_ORGANIZED: {
      const uint32_t w = n / 2;
      *c = clone_cloud(m, 2 * w * step);
      c->height = 2;
      c->width = w;
      c->row_step = w * step;
      return 1;
    }
    default:
      break;
  }
  *c = clone_cloud(m, m->data._length);
  sensor_msgs_msg_dds__PointField_* last = &c->fields._buffer[c->fields._length - 1];
  switch (d) {
    case C_POINT_STEP_SMALL:
      c->point_step = 8; /* x and y fit, z (offset 8) does not */
      break;
    case C_ROW_STEP:
      c->row_step = c->width * step / 2;
      break;
    case C_BIG_ENDIAN:
      c->is_bigendian = true;
      break;
    case C_UNKNOWN_TYPE:
    case C_BURST:
    case C_BURST_TAIL:
      last->datatype = 42;
      return d == C_BURST ? 30 : 1;
    case C_DUPLICATE_FIELD:
      free(c->fields._buffer[1].name);
      c->fields._buffer[1].name = strdup(c->fields._buffer[0].name);
      break;
    case C_MISSING_XYZ: {
      sensor_msgs_msg_dds__PointField_* z = find_field(c, "z");
      if (z) {
        free(z->name);
        z->name = strdup("zz");
      }
      break;
    }
    case C_OFFSET_BEYOND:
      last->offset = step;
      break;
    case C_STAMP_ZERO:
      c->header.stamp.sec = 0;
      c->header.stamp.nanosec = 0;
      break;
    case C_FAR_FUTURE:
      c->header.stamp.sec += 1000000;
      break;
    case C_STALE:
      c->header.stamp.sec -= 3;
      break;
    case C_HEADER_NANOSEC:
      c->header.stamp.nanosec = 4000000000u; /* out of range: read as stamp + 4 s before */
      break;
    case C_ROW_STEP_ZERO:
      c->row_step = 0; /* as some drivers publish unorganized clouds */
      break;
    case C_NO_FIELDS:
      for (uint32_t i = 0; i < c->fields._length; ++i) free(c->fields._buffer[i].name);
      c->fields._length = 0;
      break;
    case C_LONG_FRAME_ID: {
      /* Made once, kept to the end of the run (the header's frame_id is not the clone's own). */
      static char* id = NULL;
      if (!id) {
        id = (char*)malloc(kLongFrameId + 1);
        memset(id, 'f', kLongFrameId);
        id[kLongFrameId] = 0;
      }
      c->header.frame_id = id;
      break;
    }
    case C_POINT_TIME_FUTURE: {
      /* One point 1e6 s after the stamp (before: the core waited for IMU that far ahead). */
      sensor_msgs_msg_dds__PointField_* t = find_time_field(c);
      const float far = 1e6f;
      if (t && n > 0) memcpy(c->data._buffer + (size_t)(n / 2) * step + t->offset, &far, 4);
      break;
    }
    case C_POINT_TIME_PAST: {
      /* Every point 100 s before the stamp (before: a reset, "scan time went backwards"). */
      sensor_msgs_msg_dds__PointField_* t = find_time_field(c);
      const float past = -100.0f;
      for (uint32_t i = 0; t && i < n; ++i)
        memcpy(c->data._buffer + (size_t)i * step + t->offset, &past, 4);
      break;
    }
    case C_STALL: {
      sensor_msgs_msg_dds__PointField_* x = find_field(c, "x");
      if (x) x->datatype = 1; /* INT8: x must be a float */
      break;
    }
    case C_TOO_LARGE:
      c->width = 5000000; /* declared only: refused before the data is looked at */
      c->height = 1;
      c->row_step = c->width * step;
      break;
    case C_NAN_POINTS: {
      sensor_msgs_msg_dds__PointField_* x = find_field(c, "x");
      sensor_msgs_msg_dds__PointField_* y = find_field(c, "y");
      const float nan = NAN, inf = INFINITY;
      *nonfinite = 0;
      for (uint32_t i = 0; x && y && i < n; ++i) {
        if (i % 10 == 0) memcpy(c->data._buffer + (size_t)i * step + x->offset, &nan, 4);
        if (i % 10 == 5) memcpy(c->data._buffer + (size_t)i * step + y->offset, &inf, 4);
        if (i % 10 == 0 || i % 10 == 5) ++*nonfinite;
      }
      break;
    }
    default:
      break;
  }
  return 1;
}

int make_imu_defect(int d, const imu_t* m, const imu_t* held, imu_t* out) {
  *out = *m;
  switch (d) {
    case I_NAN:
      out->linear_acceleration.x = NAN;
      return 1;
    case I_ABSURD:
      out->linear_acceleration.z = 1e5;
      out->header.stamp.nanosec += out->header.stamp.nanosec < 999999000u ? 1000u : 0u;
      return 1;
    case I_ZEROS:
      memset(out, 0, sizeof(*out));
      out->header.frame_id = "";
      return 1;
    case I_DUPLICATE:
      return 1;
    case I_OUT_OF_ORDER:
      *out = *held;
      return 1;
    case I_JUMP_BACK:
      out->header.stamp.sec -= 10;
      return 1;
    case I_FUTURE:
      out->header.stamp.sec += 1000;
      return 1;
    case I_HEADER_NANOSEC:
      out->header.stamp.nanosec = 4000000000u;
      return 1;
    default:
      return 0;
  }
}
