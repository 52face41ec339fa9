/* Reading cyclone_peer's dump file (see peer_dump.h). */
#include "peer_dump.h"

#include <stdlib.h>
#include <string.h>

static int rd(FILE* f, void* p, size_t n) { return fread(p, 1, n, f) == n; }

static char* rd_str(FILE* f) {
  uint32_t n;
  if (!rd(f, &n, 4) || n > (1u << 20)) return NULL;
  char* s = (char*)malloc(n + 1);
  if (!rd(f, s, n)) {
    free(s);
    return NULL;
  }
  s[n] = 0;
  return s;
}

FILE* dump_open(const char* path) {
  FILE* f = fopen(path, "rb");
  char magic[8];
  if (!f) return NULL;
  if (!rd(f, magic, 8) || memcmp(magic, "PPFDUMP1", 8) != 0) {
    fclose(f);
    return NULL;
  }
  return f;
}

int dump_read_head(FILE* f, record_head_t* h) {
  return rd(f, &h->kind, 1) && rd(f, &h->bag_ns, 8) && rd(f, &h->sec, 4) && rd(f, &h->nsec, 4) &&
         (h->frame = rd_str(f)) != NULL;
}

int dump_read_imu(FILE* f, const record_head_t* h, imu_t* m) {
  memset(m, 0, sizeof(*m));
  m->header.stamp.sec = h->sec;
  m->header.stamp.nanosec = h->nsec;
  m->header.frame_id = h->frame;
  double q[4];
  const int ok = rd(f, q, sizeof(q)) && rd(f, m->orientation_covariance, 72) &&
                 rd(f, &m->angular_velocity, 24) && rd(f, m->angular_velocity_covariance, 72) &&
                 rd(f, &m->linear_acceleration, 24) && rd(f, m->linear_acceleration_covariance, 72);
  if (!ok) return 0;
  m->orientation.x = q[0];
  m->orientation.y = q[1];
  m->orientation.z = q[2];
  m->orientation.w = q[3];
  return 1;
}

static void free_fields(sensor_msgs_msg_dds__PointField_* fields, uint32_t nfields) {
  for (uint32_t i = 0; i < nfields; ++i) free(fields[i].name);
  free(fields);
}

int dump_read_cloud(FILE* f, const record_head_t* h, cloud_t* m) {
  memset(m, 0, sizeof(*m));
  m->header.stamp.sec = h->sec;
  m->header.stamp.nanosec = h->nsec;
  m->header.frame_id = h->frame;
  uint32_t nfields;
  if (!rd(f, &m->height, 4) || !rd(f, &m->width, 4) || !rd(f, &nfields, 4) || nfields > 64) {
    return 0;
  }
  sensor_msgs_msg_dds__PointField_* fields =
      (sensor_msgs_msg_dds__PointField_*)calloc(nfields ? nfields : 1, sizeof(*fields));
  int ok = 1;
  for (uint32_t i = 0; i < nfields && ok; ++i) {
    fields[i].name = rd_str(f);
    ok = fields[i].name && rd(f, &fields[i].offset, 4) && rd(f, &fields[i].datatype, 1) &&
         rd(f, &fields[i].count, 4);
  }
  uint8_t be = 0, dense = 0;
  uint32_t nbytes = 0;
  ok = ok && rd(f, &be, 1) && rd(f, &m->point_step, 4) && rd(f, &m->row_step, 4) &&
       rd(f, &nbytes, 4);
  uint8_t* data = ok ? (uint8_t*)malloc(nbytes ? nbytes : 1) : NULL;
  ok = ok && data && rd(f, data, nbytes) && rd(f, &dense, 1);
  if (!ok) {
    free_fields(fields, nfields);
    free(data);
    return 0;
  }
  m->fields._buffer = fields;
  m->fields._length = m->fields._maximum = nfields;
  m->fields._release = false;
  m->is_bigendian = be != 0;
  m->data._buffer = data;
  m->data._length = m->data._maximum = nbytes;
  m->data._release = false;
  m->is_dense = dense != 0;
  return 1;
}

void dump_free_cloud(cloud_t* m) {
  free_fields(m->fields._buffer, m->fields._length);
  free(m->data._buffer);
}
