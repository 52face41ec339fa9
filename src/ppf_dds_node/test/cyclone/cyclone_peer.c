/* Independent DDS peer for the interop test, on Eclipse Cyclone DDS (C API, types from idlc):
 *   - publishes ROS 2-typed Imu and PointCloud2 on rt/imu and rt/points from a dump file, with the
 *     dump's timing (a short simulated sequence: static start, then motion);
 *   - subscribes to rt/odometry (nav_msgs/Odometry) and rt/skeleton_planes
 *     (ppf_msgs/SkeletonPlaneArray) and checks what arrives.
 * Prints "READY" once all four endpoints matched, then "RESULT key=value ..." and exits 0; exits 1
 * on setup errors. Discovery follows CYCLONEDDS_URI (the test gives it the same peers as Fast DDS).
 *
 * Options after the three positional arguments:
 *   --hostile N      after the N-th cloud, inject one defect per cloud of the dump (cloud and IMU
 *                    defects alternating: cloud_names, imu_names), ending with a burst of 30
 *                    malformed clouds. A defect either follows a valid message (it must be
 *                    refused, and the next valid scan must still give odometry) or replaces a
 *                    cloud by a valid but unusual one (it must give odometry itself). Prints
 *                    "HOSTILE name=..." per defect and at the end "HOSTILE_CHECK name=... scan=S
 *                    odom=0|1": whether odometry arrived for the scan stamped S.
 *   --imu-gap S L    send no IMU from S s to S+L s after the first message (clouds go on).
 *   --max-points N   the replicated "several million points" cloud has about N points [2100000].
 *   --go-file PATH   after READY, send nothing until PATH exists (30 s at most): the test creates
 *                    it once the node has matched our writers too. Without it: 0.5 s grace.
 *
 * Dump format (little endian, written by test_cyclone from a ppf_sim bag): "PPFDUMP1", then records
 *   u8 kind (1 imu, 2 cloud), i64 bag time ns, i32 sec, u32 nanosec, str frame_id, then
 *   imu:   f64 orientation[4] (x y z w), f64 ori_cov[9], f64 gyro[3], f64 gyro_cov[9],
 *          f64 acc[3], f64 acc_cov[9]
 *   cloud: u32 height, u32 width, u32 nfields, nfields x (str name, u32 offset, u8 datatype,
 *          u32 count), u8 is_bigendian, u32 point_step, u32 row_step, u32 nbytes, bytes, u8 dense
 *   str = u32 length + bytes (no terminator). */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>
#include <string.h>
#include <time.h>

#include "dds/dds.h"
#include "ros2_types.h"

static int64_t now_ns(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (int64_t)ts.tv_sec * 1000000000LL + ts.tv_nsec;
}

static void sleep_until(int64_t t_ns) {
  int64_t d = t_ns - now_ns();
  if (d <= 0) return;
  struct timespec ts = {(time_t)(d / 1000000000LL), (long)(d % 1000000000LL)};
  nanosleep(&ts, NULL);
}

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

typedef struct {
  int odom, odom_bad, odom_frames_bad, odom_not_monotonic, planes, planes_bad, planes_total;
  double last_odom_stamp;
  double* stamps; /* every odometry stamp received, for the hostile checks */
  int n_stamps, cap_stamps;
} tally_t;

static int finite_n(const double* v, int n) {
  for (int i = 0; i < n; ++i)
    if (!isfinite(v[i])) return 0;
  return 1;
}

static void drain(dds_entity_t odom_reader, dds_entity_t planes_reader, tally_t* t) {
  void* samples[16];
  dds_sample_info_t infos[16];
  for (;;) {
    memset(samples, 0, sizeof(samples));
    int n = dds_take(odom_reader, samples, infos, 16, 16);
    if (n <= 0) break;
    for (int i = 0; i < n; ++i) {
      if (!infos[i].valid_data) continue;
      const nav_msgs_msg_dds__Odometry_* o = (const nav_msgs_msg_dds__Odometry_*)samples[i];
      const geometry_msgs_msg_dds__Pose_* p = &o->pose.pose;
      double v[13] = {p->position.x,
                      p->position.y,
                      p->position.z,
                      p->orientation.x,
                      p->orientation.y,
                      p->orientation.z,
                      p->orientation.w,
                      o->twist.twist.linear.x,
                      o->twist.twist.linear.y,
                      o->twist.twist.linear.z,
                      o->twist.twist.angular.x,
                      o->twist.twist.angular.y,
                      o->twist.twist.angular.z};
      const double qn =
          sqrt(p->orientation.x * p->orientation.x + p->orientation.y * p->orientation.y +
               p->orientation.z * p->orientation.z + p->orientation.w * p->orientation.w);
      t->odom++;
      if (!finite_n(v, 13) || !finite_n(o->pose.covariance, 36) ||
          !finite_n(o->twist.covariance, 36) || fabs(qn - 1.0) > 1e-6) {
        t->odom_bad++;
      }
      if (strcmp(o->header.frame_id, "odom") != 0 || strcmp(o->child_frame_id, "base_link") != 0)
        t->odom_frames_bad++;
      const double stamp = o->header.stamp.sec + 1e-9 * o->header.stamp.nanosec;
      if (stamp <= t->last_odom_stamp) t->odom_not_monotonic++;
      t->last_odom_stamp = stamp;
      if (t->n_stamps == t->cap_stamps) {
        t->cap_stamps = t->cap_stamps ? 2 * t->cap_stamps : 256;
        t->stamps = (double*)realloc(t->stamps, (size_t)t->cap_stamps * sizeof(double));
      }
      t->stamps[t->n_stamps++] = stamp;
    }
    dds_return_loan(odom_reader, samples, n);
  }
  for (;;) {
    memset(samples, 0, sizeof(samples));
    int n = dds_take(planes_reader, samples, infos, 16, 16);
    if (n <= 0) break;
    for (int i = 0; i < n; ++i) {
      if (!infos[i].valid_data) continue;
      const ppf_msgs_msg_dds__SkeletonPlaneArray_* a =
          (const ppf_msgs_msg_dds__SkeletonPlaneArray_*)samples[i];
      t->planes++;
      t->planes_total += (int)a->planes._length;
      int bad = strcmp(a->header.frame_id, "odom") != 0;
      for (uint32_t k = 0; k < a->planes._length; ++k) {
        const ppf_msgs_msg_dds__SkeletonPlane_* pl = &a->planes._buffer[k];
        const double nn = sqrt(pl->normal.x * pl->normal.x + pl->normal.y * pl->normal.y +
                               pl->normal.z * pl->normal.z);
        if (!isfinite(pl->offset) || fabs(nn - 1.0) > 1e-6) bad = 1;
      }
      t->planes_bad += bad;
    }
    dds_return_loan(planes_reader, samples, n);
  }
}

/* ---- hostile mode ------------------------------------------------------------------------- */

typedef sensor_msgs_msg_dds__PointCloud2_ cloud_t;
typedef sensor_msgs_msg_dds__Imu_ imu_t;

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

static void free_cloud(cloud_t* c) {
  for (uint32_t i = 0; i < c->fields._length; ++i) free(c->fields._buffer[i].name);
  free(c->fields._buffer);
  free(c->data._buffer);
}

static sensor_msgs_msg_dds__PointField_* find_field(cloud_t* c, const char* name) {
  for (uint32_t i = 0; i < c->fields._length; ++i)
    if (strcmp(c->fields._buffer[i].name, name) == 0) return &c->fields._buffer[i];
  return NULL;
}

/* Defects of a cloud, built from the valid cloud just sent (or in place of it: kReplace). */
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
static const char* const cloud_names[C_COUNT] = {
    "point_step_small", "data_short",      "data_long",   "row_step",      "big_endian",
    "unknown_type",     "duplicate_field", "missing_xyz", "offset_beyond", "empty",
    "stamp_zero",       "far_future",      "stale",       "too_large",     "huge",
    "nan_points",       "organized",       "burst",       "burst_tail"};
static int cloud_replaces(int d) { return d == C_HUGE || d == C_NAN_POINTS || d == C_ORGANIZED; }

enum { I_NAN, I_ABSURD, I_ZEROS, I_DUPLICATE, I_OUT_OF_ORDER, I_JUMP_BACK, I_FUTURE, I_COUNT };
static const char* const imu_names[I_COUNT] = {"imu_nan",       "imu_absurd",       "imu_zeros",
                                               "imu_duplicate", "imu_out_of_order", "imu_jump_back",
                                               "imu_future"};

/* Builds defect d from valid cloud m into *c (which the caller writes, then frees). Returns the
 * number of copies to write. */
static int make_cloud_defect(int d, const cloud_t* m, size_t max_points, cloud_t* c,
                             int* nonfinite) {
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

typedef struct {
  const char* name;
  double check; /* stamp of the scan whose odometry must arrive; <0 until known */
} check_t;

/* Odometry for the scan stamped s (header at scan start, 10 Hz): stamped at the scan's last
 * point, s + ~0.1 s; the scan before ends just before s, the next one at s + ~0.2 s. */
static int odom_for(const tally_t* t, double s) {
  for (int i = 0; i < t->n_stamps; ++i)
    if (t->stamps[i] > s + 0.05 && t->stamps[i] < s + 0.15) return 1;
  return 0;
}

int main(int argc, char** argv) {
  if (argc < 4) {
    fprintf(stderr, "usage: %s DUMP DOMAIN WAIT_S\n", argv[0]);
    return 2;
  }
  FILE* f = fopen(argv[1], "rb");
  char magic[8];
  if (!f || !rd(f, magic, 8) || memcmp(magic, "PPFDUMP1", 8) != 0) {
    fprintf(stderr, "cyclone_peer: cannot read dump %s\n", argv[1]);
    return 1;
  }
  const dds_domainid_t domain = (dds_domainid_t)atoi(argv[2]);
  const double wait_s = atof(argv[3]);
  int hostile_from = -1;
  double gap_start = -1, gap_len = 0;
  size_t max_points = 2100000;
  const char* go_file = NULL;
  for (int i = 4; i < argc; ++i) {
    if (strcmp(argv[i], "--hostile") == 0 && i + 1 < argc) {
      hostile_from = atoi(argv[++i]);
    } else if (strcmp(argv[i], "--imu-gap") == 0 && i + 2 < argc) {
      gap_start = atof(argv[++i]);
      gap_len = atof(argv[++i]);
    } else if (strcmp(argv[i], "--max-points") == 0 && i + 1 < argc) {
      max_points = (size_t)atoll(argv[++i]);
    } else if (strcmp(argv[i], "--go-file") == 0 && i + 1 < argc) {
      go_file = argv[++i];
    } else {
      fprintf(stderr, "cyclone_peer: unknown option %s\n", argv[i]);
      return 2;
    }
  }

  dds_entity_t pp = dds_create_participant(domain, NULL, NULL);
  if (pp < 0) {
    fprintf(stderr, "cyclone_peer: dds_create_participant: %s\n", dds_strretcode(-pp));
    return 1;
  }
  dds_entity_t t_points =
      dds_create_topic(pp, &sensor_msgs_msg_dds__PointCloud2__desc, "rt/points", NULL, NULL);
  dds_entity_t t_imu = dds_create_topic(pp, &sensor_msgs_msg_dds__Imu__desc, "rt/imu", NULL, NULL);
  dds_entity_t t_odom =
      dds_create_topic(pp, &nav_msgs_msg_dds__Odometry__desc, "rt/odometry", NULL, NULL);
  dds_entity_t t_planes = dds_create_topic(pp, &ppf_msgs_msg_dds__SkeletonPlaneArray__desc,
                                           "rt/skeleton_planes", NULL, NULL);
  if (t_points < 0 || t_imu < 0 || t_odom < 0 || t_planes < 0) {
    fprintf(stderr, "cyclone_peer: topic creation failed\n");
    return 1;
  }
  /* XCDR1, as ROS 2 uses on the wire in every distro. Reliable writers match both reliable and
   * best-effort readers; the node reads best effort by default. */
  dds_data_representation_id_t xcdr1[1] = {DDS_DATA_REPRESENTATION_XCDR1};
  dds_qos_t* wq = dds_create_qos();
  dds_qset_reliability(wq, DDS_RELIABILITY_RELIABLE, DDS_SECS(2));
  dds_qset_history(wq, DDS_HISTORY_KEEP_LAST, 200);
  dds_qset_data_representation(wq, 1, xcdr1);
  dds_entity_t w_points = dds_create_writer(pp, t_points, wq, NULL);
  dds_entity_t w_imu = dds_create_writer(pp, t_imu, wq, NULL);
  dds_qos_t* rq = dds_create_qos();
  dds_qset_reliability(rq, DDS_RELIABILITY_RELIABLE, DDS_SECS(2));
  dds_qset_history(rq, DDS_HISTORY_KEEP_ALL, 0);
  dds_qset_data_representation(rq, 1, xcdr1);
  dds_entity_t r_odom = dds_create_reader(pp, t_odom, rq, NULL);
  dds_entity_t r_planes = dds_create_reader(pp, t_planes, rq, NULL);
  dds_delete_qos(wq);
  dds_delete_qos(rq);
  if (w_points < 0 || w_imu < 0 || r_odom < 0 || r_planes < 0) {
    fprintf(stderr, "cyclone_peer: endpoint creation failed\n");
    return 1;
  }

  const int64_t match_deadline = now_ns() + 20000000000LL;
  int matched = 0;
  while (!matched && now_ns() < match_deadline) {
    dds_publication_matched_status_t p1, p2;
    dds_subscription_matched_status_t s1, s2;
    dds_get_publication_matched_status(w_points, &p1);
    dds_get_publication_matched_status(w_imu, &p2);
    dds_get_subscription_matched_status(r_odom, &s1);
    dds_get_subscription_matched_status(r_planes, &s2);
    matched = p1.current_count > 0 && p2.current_count > 0 && s1.current_count > 0 &&
              s2.current_count > 0;
    if (!matched) dds_sleepfor(DDS_MSECS(20));
  }
  if (!matched) {
    printf("RESULT error=not_matched\n");
    fflush(stdout);
    dds_delete(pp);
    return 1;
  }
  printf("READY\n");
  fflush(stdout);
  /* Our writers matching says nothing of the node's readers matching them (what is sent before
   * that is dropped by a volatile reader). With --go-file the test creates the file once the
   * node's log says so; without it, a moment's grace. */
  if (go_file) {
    const int64_t go_deadline = now_ns() + DDS_SECS(30);
    while (access(go_file, F_OK) != 0 && now_ns() < go_deadline) dds_sleepfor(DDS_MSECS(10));
    if (access(go_file, F_OK) != 0) {
      printf("RESULT error=no_go_file\n");
      fflush(stdout);
      dds_delete(pp);
      return 1;
    }
  } else {
    dds_sleepfor(DDS_MSECS(500));
  }

  tally_t t;
  memset(&t, 0, sizeof(t));
  int sent_scans = 0, sent_imu = 0, write_errors = 0, skipped_imu = 0, defects_sent = 0;
  int64_t wall0 = 0, bag0 = 0;
  int first = 1;
  int clouds_read = 0, hostile_step = 0, imu_defect = -1;
  check_t checks[64];
  int n_checks = 0;
  imu_t held; /* I_OUT_OF_ORDER: the sample sent after its successor */
  int holding = 0;
  uint8_t kind;
  while (rd(f, &kind, 1)) {
    int64_t bag_ns;
    int32_t sec;
    uint32_t nsec;
    char* frame;
    if (!rd(f, &bag_ns, 8) || !rd(f, &sec, 4) || !rd(f, &nsec, 4) || !(frame = rd_str(f))) break;
    if (first) {
      wall0 = now_ns();
      bag0 = bag_ns;
      first = 0;
    }
    sleep_until(wall0 + (bag_ns - bag0));
    if (kind == 1) {
      sensor_msgs_msg_dds__Imu_ m;
      memset(&m, 0, sizeof(m));
      m.header.stamp.sec = sec;
      m.header.stamp.nanosec = nsec;
      m.header.frame_id = frame;
      double q[4];
      int ok = rd(f, q, sizeof(q)) && rd(f, m.orientation_covariance, 72) &&
               rd(f, &m.angular_velocity, 24) && rd(f, m.angular_velocity_covariance, 72) &&
               rd(f, &m.linear_acceleration, 24) && rd(f, m.linear_acceleration_covariance, 72);
      if (!ok) break;
      m.orientation.x = q[0];
      m.orientation.y = q[1];
      m.orientation.z = q[2];
      m.orientation.w = q[3];
      if (gap_start >= 0 && bag_ns - bag0 >= (int64_t)(gap_start * 1e9) &&
          bag_ns - bag0 < (int64_t)((gap_start + gap_len) * 1e9)) {
        skipped_imu++; /* the IMU falls silent, the LiDAR goes on */
      } else if (imu_defect == I_OUT_OF_ORDER && !holding) {
        held = m;
        held.header.frame_id = strdup(frame);
        holding = 1;
      } else {
        if (dds_write(w_imu, &m) < 0)
          write_errors++;
        else
          sent_imu++;
        imu_t d = m;
        int send = 1;
        switch (imu_defect) {
          case I_NAN:
            d.linear_acceleration.x = NAN;
            break;
          case I_ABSURD:
            d.linear_acceleration.z = 1e5;
            d.header.stamp.nanosec += d.header.stamp.nanosec < 999999000u ? 1000u : 0u;
            break;
          case I_ZEROS:
            memset(&d, 0, sizeof(d));
            d.header.frame_id = "";
            break;
          case I_DUPLICATE:
            break;
          case I_OUT_OF_ORDER:
            d = held;
            break;
          case I_JUMP_BACK:
            d.header.stamp.sec -= 10;
            break;
          case I_FUTURE:
            d.header.stamp.sec += 1000;
            break;
          default:
            send = 0;
        }
        if (send) {
          if (dds_write(w_imu, &d) < 0) write_errors++;
          defects_sent++;
          if (imu_defect == I_OUT_OF_ORDER) {
            free(held.header.frame_id);
            holding = 0;
          }
          imu_defect = -1;
        }
      }
    } else if (kind == 2) {
      sensor_msgs_msg_dds__PointCloud2_ m;
      memset(&m, 0, sizeof(m));
      m.header.stamp.sec = sec;
      m.header.stamp.nanosec = nsec;
      m.header.frame_id = frame;
      uint32_t nfields;
      if (!rd(f, &m.height, 4) || !rd(f, &m.width, 4) || !rd(f, &nfields, 4) || nfields > 64) break;
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
      ok = ok && rd(f, &be, 1) && rd(f, &m.point_step, 4) && rd(f, &m.row_step, 4) &&
           rd(f, &nbytes, 4);
      uint8_t* data = ok ? (uint8_t*)malloc(nbytes ? nbytes : 1) : NULL;
      ok = ok && data && rd(f, data, nbytes) && rd(f, &dense, 1);
      if (ok) {
        m.fields._buffer = fields;
        m.fields._length = m.fields._maximum = nfields;
        m.fields._release = false;
        m.is_bigendian = be != 0;
        m.data._buffer = data;
        m.data._length = m.data._maximum = nbytes;
        m.data._release = false;
        m.is_dense = dense != 0;
        const double stamp = sec + 1e-9 * nsec;
        ++clouds_read;
        for (int i = 0; i < n_checks; ++i)
          if (checks[i].check < 0) checks[i].check = stamp;
        int defect = -1;
        if (hostile_from >= 0 && clouds_read > hostile_from) {
          const int j = hostile_step++;
          if (j % 2 == 0 && j / 2 < C_COUNT) defect = j / 2;
          if (j % 2 == 1 && j / 2 < I_COUNT) {
            imu_defect = j / 2;
            checks[n_checks].name = imu_names[j / 2];
            checks[n_checks++].check = -1; /* the next scan */
            printf("HOSTILE name=%s\n", imu_names[j / 2]);
          }
        }
        cloud_t c;
        int nonfinite = 0, copies = 0;
        if (defect >= 0) copies = make_cloud_defect(defect, &m, max_points, &c, &nonfinite);
        /* A replacing defect takes the valid cloud's place; the others follow it. */
        if (dds_write(w_points, defect >= 0 && cloud_replaces(defect) ? &c : &m) < 0)
          write_errors++;
        else
          sent_scans++;
        if (defect >= 0) {
          if (cloud_replaces(defect)) {
            checks[n_checks].name = cloud_names[defect];
            checks[n_checks++].check = stamp;
          } else {
            for (int k = 0; k < copies; ++k)
              if (dds_write(w_points, &c) < 0) write_errors++;
            checks[n_checks].name = cloud_names[defect];
            checks[n_checks++].check = -1;
          }
          /* Tens of MB go out as tens of thousands of UDP fragments, more than the socket
           * buffers hold: let the reliable protocol repair them before the next scan competes. */
          if (defect == C_HUGE) dds_wait_for_acks(w_points, DDS_SECS(20));
          defects_sent += copies;
          printf("HOSTILE name=%s points=%u nonfinite=%d copies=%d\n", cloud_names[defect],
                 c.width * c.height, nonfinite, copies);
          fflush(stdout);
          free_cloud(&c);
        }
      }
      for (uint32_t i = 0; i < nfields; ++i) free(fields[i].name);
      free(fields);
      free(data);
      if (!ok) {
        free(frame);
        break;
      }
    } else {
      free(frame);
      break;
    }
    free(frame);
    drain(r_odom, r_planes, &t);
  }
  fclose(f);

  /* Wait for the node to finish: until no odometry arrived for 3 s, at most wait_s. */
  const int64_t end = now_ns() + (int64_t)(wait_s * 1e9);
  int64_t last_change = now_ns();
  int last_count = t.odom;
  while (now_ns() < end && now_ns() - last_change < 3000000000LL) {
    dds_sleepfor(DDS_MSECS(50));
    drain(r_odom, r_planes, &t);
    if (t.odom != last_count) {
      last_count = t.odom;
      last_change = now_ns();
    }
  }
  int checks_failed = 0;
  for (int i = 0; i < n_checks; ++i) {
    const int ok = checks[i].check >= 0 && odom_for(&t, checks[i].check);
    checks_failed += !ok;
    printf("HOSTILE_CHECK name=%s scan=%.6f odom=%d\n", checks[i].name, checks[i].check, ok);
  }
  printf(
      "RESULT sent_scans=%d sent_imu=%d write_errors=%d odom=%d odom_bad=%d odom_frames_bad=%d "
      "odom_not_monotonic=%d planes=%d planes_bad=%d planes_total=%d skipped_imu=%d "
      "defects_sent=%d hostile_checks=%d hostile_checks_failed=%d\n",
      sent_scans, sent_imu, write_errors, t.odom, t.odom_bad, t.odom_frames_bad,
      t.odom_not_monotonic, t.planes, t.planes_bad, t.planes_total, skipped_imu, defects_sent,
      n_checks, checks_failed);
  fflush(stdout);
  free(t.stamps);
  dds_delete(pp);
  return 0;
}
