/* cyclone_peer's defects (see peer_hostile.h). */
#include "peer_hostile.h"

#include <math.h>
#include <stdint.h>
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

const char* const cloud_names[C_COUNT] = {
    "point_step_small", "data_short",      "data_long",   "row_step",      "big_endian",
    "unknown_type",     "duplicate_field", "missing_xyz", "offset_beyond", "empty",
    "stamp_zero",       "far_future",      "stale",       "too_large",     "huge",
    "nan_points",       "organized",       "burst",       "burst_tail"};
int cloud_replaces(int d) { return d == C_HUGE || d == C_NAN_POINTS || d == C_ORGANIZED; }

const char* const imu_names[I_COUNT] = {"imu_nan",       "imu_absurd",       "imu_zeros",
                                        "imu_duplicate", "imu_out_of_order", "imu_jump_back",
                                        "imu_future"};

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
    default:
      return 0;
  }
}
