/* Independent DDS peer for the interop test, on Eclipse Cyclone DDS (C API, types from idlc):
 *   - publishes ROS 2-typed Imu and PointCloud2 on rt/imu and rt/points from a dump file, with the
 *     dump's timing (a short simulated sequence: static start, then motion);
 *   - subscribes to rt/odometry (nav_msgs/Odometry) and rt/skeleton_planes
 *     (ppf_msgs/SkeletonPlaneArray) and checks what arrives.
 * Prints "READY" once all four endpoints matched, then "RESULT key=value ..." and exits 0; exits 1
 * on setup errors. Discovery follows CYCLONEDDS_URI (the test gives it the same peers as Fast DDS).
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
  /* Discovery is symmetric but not simultaneous: give the node's readers a moment as well. */
  dds_sleepfor(DDS_MSECS(500));

  tally_t t;
  memset(&t, 0, sizeof(t));
  int sent_scans = 0, sent_imu = 0, write_errors = 0;
  int64_t wall0 = 0, bag0 = 0;
  int first = 1;
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
      if (dds_write(w_imu, &m) < 0)
        write_errors++;
      else
        sent_imu++;
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
        if (dds_write(w_points, &m) < 0)
          write_errors++;
        else
          sent_scans++;
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
  printf(
      "RESULT sent_scans=%d sent_imu=%d write_errors=%d odom=%d odom_bad=%d odom_frames_bad=%d "
      "odom_not_monotonic=%d planes=%d planes_bad=%d planes_total=%d\n",
      sent_scans, sent_imu, write_errors, t.odom, t.odom_bad, t.odom_frames_bad,
      t.odom_not_monotonic, t.planes, t.planes_bad, t.planes_total);
  fflush(stdout);
  dds_delete(pp);
  return 0;
}
