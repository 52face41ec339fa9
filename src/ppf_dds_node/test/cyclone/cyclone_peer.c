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
 *                    defects alternating while IMU ones are left: cloud_names, imu_names), among
 *                    them 2 s of clouds each replaced by a malformed copy (stall), ending with
 *                    a burst of 30 malformed clouds. A defect either follows a valid message (it
 *                    must be refused, and the next valid scan must still give odometry) or
 *                    replaces a cloud by a valid but unusual one (it must give odometry itself),
 *                    or by a malformed one (stall: the scan after it must). Prints
 *                    "HOSTILE name=..." per defect and at the end "HOSTILE_CHECK name=... scan=S
 *                    odom=0|1": whether odometry arrived for the scan stamped S.
 *   --imu-gap S L    send no IMU from S s to S+L s after the first message (clouds go on).
 *   --imu-clock-offset S D  from S s after the first message on, stamp every IMU sample D s
 *                    earlier (the IMU's clock falls behind the LiDAR's and stays there).
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
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "dds/dds.h"
#include "peer_dump.h"
#include "peer_hostile.h"
#include "peer_tally.h"
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

typedef struct {
  dds_domainid_t domain;
  double wait_s;
  int hostile_from;
  double gap_start, gap_len;
  double offset_start, offset_s;
  size_t max_points;
  const char* go_file;
} options_t;

/* The options after the three positional arguments; 0 (and a message) on an unknown one. */
static int parse_options(int argc, char** argv, options_t* o) {
  o->domain = (dds_domainid_t)atoi(argv[2]);
  o->wait_s = atof(argv[3]);
  o->hostile_from = -1;
  o->gap_start = -1;
  o->gap_len = 0;
  o->offset_start = -1;
  o->offset_s = 0;
  o->max_points = 2100000;
  o->go_file = NULL;
  for (int i = 4; i < argc; ++i) {
    if (strcmp(argv[i], "--hostile") == 0 && i + 1 < argc) {
      o->hostile_from = atoi(argv[++i]);
    } else if (strcmp(argv[i], "--imu-gap") == 0 && i + 2 < argc) {
      o->gap_start = atof(argv[++i]);
      o->gap_len = atof(argv[++i]);
    } else if (strcmp(argv[i], "--imu-clock-offset") == 0 && i + 2 < argc) {
      o->offset_start = atof(argv[++i]);
      o->offset_s = atof(argv[++i]);
    } else if (strcmp(argv[i], "--max-points") == 0 && i + 1 < argc) {
      o->max_points = (size_t)atoll(argv[++i]);
    } else if (strcmp(argv[i], "--go-file") == 0 && i + 1 < argc) {
      o->go_file = argv[++i];
    } else {
      fprintf(stderr, "cyclone_peer: unknown option %s\n", argv[i]);
      return 0;
    }
  }
  return 1;
}

typedef struct {
  dds_entity_t pp, w_points, w_imu, r_odom, r_planes;
} endpoints_t;

/* The participant and its four endpoints; 0 (and a message) if any cannot be made. */
static int create_endpoints(dds_domainid_t domain, endpoints_t* e) {
  e->pp = dds_create_participant(domain, NULL, NULL);
  if (e->pp < 0) {
    fprintf(stderr, "cyclone_peer: dds_create_participant: %s\n", dds_strretcode(-e->pp));
    return 0;
  }
  dds_entity_t t_points =
      dds_create_topic(e->pp, &sensor_msgs_msg_dds__PointCloud2__desc, "rt/points", NULL, NULL);
  dds_entity_t t_imu =
      dds_create_topic(e->pp, &sensor_msgs_msg_dds__Imu__desc, "rt/imu", NULL, NULL);
  dds_entity_t t_odom =
      dds_create_topic(e->pp, &nav_msgs_msg_dds__Odometry__desc, "rt/odometry", NULL, NULL);
  dds_entity_t t_planes = dds_create_topic(e->pp, &ppf_msgs_msg_dds__SkeletonPlaneArray__desc,
                                           "rt/skeleton_planes", NULL, NULL);
  if (t_points < 0 || t_imu < 0 || t_odom < 0 || t_planes < 0) {
    fprintf(stderr, "cyclone_peer: topic creation failed\n");
    return 0;
  }
  /* XCDR1, as ROS 2 uses on the wire in every distro. Reliable writers match both reliable and
   * best-effort readers; the node reads best effort by default. */
  dds_data_representation_id_t xcdr1[1] = {DDS_DATA_REPRESENTATION_XCDR1};
  dds_qos_t* wq = dds_create_qos();
  dds_qset_reliability(wq, DDS_RELIABILITY_RELIABLE, DDS_SECS(2));
  dds_qset_history(wq, DDS_HISTORY_KEEP_LAST, 200);
  dds_qset_data_representation(wq, 1, xcdr1);
  e->w_points = dds_create_writer(e->pp, t_points, wq, NULL);
  /* IMU: 10 s of 200 Hz kept for retransmission. While the node's receive thread decodes a huge
   * cloud (seconds when instrumented) IMU datagrams overflow its socket buffer; a 1 s history had
   * already moved on when the node asked for them again, and they were lost to the test. */
  dds_qset_history(wq, DDS_HISTORY_KEEP_LAST, 2000);
  e->w_imu = dds_create_writer(e->pp, t_imu, wq, NULL);
  dds_qos_t* rq = dds_create_qos();
  dds_qset_reliability(rq, DDS_RELIABILITY_RELIABLE, DDS_SECS(2));
  dds_qset_history(rq, DDS_HISTORY_KEEP_ALL, 0);
  dds_qset_data_representation(rq, 1, xcdr1);
  e->r_odom = dds_create_reader(e->pp, t_odom, rq, NULL);
  e->r_planes = dds_create_reader(e->pp, t_planes, rq, NULL);
  dds_delete_qos(wq);
  dds_delete_qos(rq);
  if (e->w_points < 0 || e->w_imu < 0 || e->r_odom < 0 || e->r_planes < 0) {
    fprintf(stderr, "cyclone_peer: endpoint creation failed\n");
    return 0;
  }
  return 1;
}

/* Until all four endpoints matched (20 s at most), then READY, then until we may send. 0 after
 * printing the RESULT error line if either never happens. */
static int wait_matched_and_go(const endpoints_t* e, const char* go_file) {
  const int64_t match_deadline = now_ns() + 20000000000LL;
  int matched = 0;
  while (!matched && now_ns() < match_deadline) {
    dds_publication_matched_status_t p1, p2;
    dds_subscription_matched_status_t s1, s2;
    dds_get_publication_matched_status(e->w_points, &p1);
    dds_get_publication_matched_status(e->w_imu, &p2);
    dds_get_subscription_matched_status(e->r_odom, &s1);
    dds_get_subscription_matched_status(e->r_planes, &s2);
    matched = p1.current_count > 0 && p2.current_count > 0 && s1.current_count > 0 &&
              s2.current_count > 0;
    if (!matched) dds_sleepfor(DDS_MSECS(20));
  }
  if (!matched) {
    printf("RESULT error=not_matched\n");
    fflush(stdout);
    return 0;
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
      return 0;
    }
  } else {
    dds_sleepfor(DDS_MSECS(500));
  }
  return 1;
}

typedef struct {
  const char* name;
  double check; /* stamp of the scan whose odometry must arrive; <0 until known */
} check_t;

/* The replay's state: what was sent, and the hostile mode's progress and pending checks. */
typedef struct {
  const options_t* o;
  const endpoints_t* e;
  int sent_scans, sent_imu, write_errors, skipped_imu, defects_sent, offset_imu;
  int64_t bag0;
  int clouds_read, hostile_step, imu_defect, stall_left, conflict_left;
  double last_plain; /* stamp of the last cloud sent as it was read (<0: none yet) */
  check_t checks[64];
  int n_checks;
  imu_t held; /* I_OUT_OF_ORDER: the sample sent after its successor */
  int holding;
} replay_t;

static void send_imu(replay_t* r, const record_head_t* h, const imu_t* orig) {
  const options_t* o = r->o;
  if (o->gap_start >= 0 && h->bag_ns - r->bag0 >= (int64_t)(o->gap_start * 1e9) &&
      h->bag_ns - r->bag0 < (int64_t)((o->gap_start + o->gap_len) * 1e9)) {
    r->skipped_imu++; /* the IMU falls silent, the LiDAR goes on */
    return;
  }
  imu_t shifted = *orig;
  const imu_t* m = orig;
  if (o->offset_start >= 0 && h->bag_ns - r->bag0 >= (int64_t)(o->offset_start * 1e9)) {
    /* The IMU's clock behind the LiDAR's from here on; the sample itself is valid. */
    const int64_t ns = (int64_t)shifted.header.stamp.sec * 1000000000LL +
                       shifted.header.stamp.nanosec - (int64_t)(o->offset_s * 1e9);
    shifted.header.stamp.sec = (int32_t)(ns / 1000000000LL);
    shifted.header.stamp.nanosec = (uint32_t)(ns % 1000000000LL);
    m = &shifted;
    r->offset_imu++;
  }
  if (r->imu_defect == I_CONFLICT) {
    r->conflict_left = kConflictSamples;
    r->imu_defect = -1;
  }
  if (r->conflict_left > 0) {
    /* The wrong copy first: a receiver keeping the first by arrival keeps the wrong one. */
    imu_t bad = *m;
    bad.linear_acceleration.x += 5.0;
    bad.angular_velocity.z += 1.0;
    if (dds_write(r->e->w_imu, &bad) < 0) r->write_errors++;
    r->defects_sent++;
    r->conflict_left--;
  }
  if (r->imu_defect == I_OUT_OF_ORDER && !r->holding) {
    r->held = *m;
    r->held.header.frame_id = strdup(h->frame);
    r->holding = 1;
    return;
  }
  if (dds_write(r->e->w_imu, m) < 0)
    r->write_errors++;
  else
    r->sent_imu++;
  imu_t d;
  if (make_imu_defect(r->imu_defect, m, &r->held, &d)) {
    if (dds_write(r->e->w_imu, &d) < 0) r->write_errors++;
    r->defects_sent++;
    if (r->imu_defect == I_OUT_OF_ORDER) {
      free(r->held.header.frame_id);
      r->holding = 0;
    }
    r->imu_defect = -1;
  }
}

/* C_STALL: valid cloud m goes out as its malformed copy; after the last one the next scan must
 * give odometry again. */
static void send_stall_copy(replay_t* r, const cloud_t* m) {
  cloud_t c;
  int nonfinite = 0;
  make_cloud_defect(C_STALL, m, r->o->max_points, &c, &nonfinite);
  if (dds_write(r->e->w_points, &c) < 0)
    r->write_errors++;
  else
    r->sent_scans++;
  free_cloud(&c);
  if (--r->stall_left == 0) {
    r->checks[r->n_checks].name = cloud_names[C_STALL];
    r->checks[r->n_checks++].check = -1;
  }
}

static void send_cloud(replay_t* r, const cloud_t* m) {
  const double stamp = m->header.stamp.sec + 1e-9 * m->header.stamp.nanosec;
  ++r->clouds_read;
  /* A cloud that cannot give odometry does not answer the pending checks: the next one does. */
  if (r->stall_left > 0) {
    send_stall_copy(r, m);
    return;
  }
  int defect = -1, imu_defect = -1;
  if (r->o->hostile_from >= 0 && r->clouds_read > r->o->hostile_from) {
    /* Cloud and IMU defects alternate while there are IMU defects left, then one cloud defect
     * per cloud. */
    const int j = r->hostile_step++;
    if (j < 2 * I_COUNT) {
      if (j % 2 == 0) defect = j / 2;
      if (j % 2 == 1) imu_defect = j / 2;
    } else if (I_COUNT + (j - 2 * I_COUNT) < C_COUNT) {
      defect = I_COUNT + (j - 2 * I_COUNT);
    }
  }
  if (defect < 0 || !cloud_replaces_unusable(defect)) {
    for (int i = 0; i < r->n_checks; ++i)
      if (r->checks[i].check < 0) r->checks[i].check = stamp;
  }
  if (imu_defect >= 0) {
    r->imu_defect = imu_defect;
    r->checks[r->n_checks].name = imu_names[imu_defect];
    r->checks[r->n_checks++].check = -1; /* the next scan */
    printf("HOSTILE name=%s\n", imu_names[imu_defect]);
  }
  if (defect >= 0 && cloud_replaces_unusable(defect) && defect != C_STALL) {
    cloud_t c;
    int nonfinite = 0;
    make_cloud_defect(defect, m, r->o->max_points, &c, &nonfinite);
    if (dds_write(r->e->w_points, &c) < 0)
      r->write_errors++;
    else
      r->sent_scans++;
    r->defects_sent++;
    r->checks[r->n_checks].name = cloud_names[defect];
    r->checks[r->n_checks++].check = -1; /* the next scan */
    printf("HOSTILE name=%s points=%u\n", cloud_names[defect], c.width * c.height);
    fflush(stdout);
    free_cloud(&c);
    return;
  }
  if (defect == C_STALL) {
    printf("HOSTILE name=%s copies=%d\n", cloud_names[C_STALL], kStallClouds);
    fflush(stdout);
    r->defects_sent += kStallClouds;
    r->stall_left = kStallClouds;
    send_stall_copy(r, m);
    return;
  }
  cloud_t c;
  int nonfinite = 0, copies = 0;
  if (defect >= 0) copies = make_cloud_defect(defect, m, r->o->max_points, &c, &nonfinite);
  /* A replacing defect takes the valid cloud's place; the others follow it. */
  if (dds_write(r->e->w_points, defect >= 0 && cloud_replaces(defect) ? &c : m) < 0) {
    r->write_errors++;
  } else {
    r->sent_scans++;
    if (defect < 0 || !cloud_replaces(defect)) r->last_plain = stamp;
  }
  if (defect < 0) return;
  if (cloud_replaces(defect)) {
    r->checks[r->n_checks].name = cloud_names[defect];
    r->checks[r->n_checks++].check = stamp;
  } else {
    for (int k = 0; k < copies; ++k)
      if (dds_write(r->e->w_points, &c) < 0) r->write_errors++;
    r->checks[r->n_checks].name = cloud_names[defect];
    r->checks[r->n_checks++].check = -1;
  }
  /* Tens of MB go out as tens of thousands of UDP fragments, more than the socket buffers hold:
   * let the reliable protocol repair them before the next scan competes. */
  if (defect == C_HUGE) dds_wait_for_acks(r->e->w_points, DDS_SECS(20));
  r->defects_sent += copies;
  printf("HOSTILE name=%s points=%u nonfinite=%d copies=%d\n", cloud_names[defect],
         c.width * c.height, nonfinite, copies);
  fflush(stdout);
  free_cloud(&c);
}

/* Sends the dump's records with the dump's timing, taking what the node sends between them. */
static void replay(FILE* f, replay_t* r, tally_t* t) {
  int64_t wall0 = 0;
  int first = 1;
  record_head_t h;
  while (dump_read_head(f, &h)) {
    if (first) {
      wall0 = now_ns();
      r->bag0 = h.bag_ns;
      first = 0;
    }
    sleep_until(wall0 + (h.bag_ns - r->bag0));
    int ok = 0;
    if (h.kind == 1) {
      imu_t m;
      ok = dump_read_imu(f, &h, &m);
      if (ok) send_imu(r, &h, &m);
    } else if (h.kind == 2) {
      cloud_t m;
      ok = dump_read_cloud(f, &h, &m);
      if (ok) {
        send_cloud(r, &m);
        dump_free_cloud(&m);
      }
    }
    free(h.frame);
    if (!ok) break;
    drain(r->e->r_odom, r->e->r_planes, t);
  }
}

/* Waits for the node to finish, at most wait_s: until the odometry for the last cloud sent as it
 * was read has arrived (odometry comes in scan order, so nothing follows it), or, should that
 * scan give none, until no odometry arrived for 10 s. A node under a sanitizer can be silent for
 * several seconds while it takes in a huge cloud with scans queued behind it. */
static void wait_for_last_odometry(const endpoints_t* e, double wait_s, double last_plain,
                                   tally_t* t) {
  const int64_t end = now_ns() + (int64_t)(wait_s * 1e9);
  int64_t last_change = now_ns();
  int last_count = t->odom;
  while (now_ns() < end && now_ns() - last_change < 10000000000LL) {
    if (last_plain >= 0 && odom_for(t, last_plain)) break;
    dds_sleepfor(DDS_MSECS(50));
    drain(e->r_odom, e->r_planes, t);
    if (t->odom != last_count) {
      last_count = t->odom;
      last_change = now_ns();
    }
  }
}

static void print_results(const replay_t* r, const tally_t* t) {
  int checks_failed = 0;
  for (int i = 0; i < r->n_checks; ++i) {
    const int ok = r->checks[i].check >= 0 && odom_for(t, r->checks[i].check);
    checks_failed += !ok;
    printf("HOSTILE_CHECK name=%s scan=%.6f odom=%d\n", r->checks[i].name, r->checks[i].check,
           ok);
  }
  printf(
      "RESULT sent_scans=%d sent_imu=%d write_errors=%d odom=%d odom_bad=%d odom_frames_bad=%d "
      "odom_not_monotonic=%d planes=%d planes_bad=%d planes_total=%d skipped_imu=%d "
      "defects_sent=%d hostile_checks=%d hostile_checks_failed=%d offset_imu=%d\n",
      r->sent_scans, r->sent_imu, r->write_errors, t->odom, t->odom_bad, t->odom_frames_bad,
      t->odom_not_monotonic, t->planes, t->planes_bad, t->planes_total, r->skipped_imu,
      r->defects_sent, r->n_checks, checks_failed, r->offset_imu);
  fflush(stdout);
}

int main(int argc, char** argv) {
  if (argc < 4) {
    fprintf(stderr, "usage: %s DUMP DOMAIN WAIT_S\n", argv[0]);
    return 2;
  }
  FILE* f = dump_open(argv[1]);
  if (!f) {
    fprintf(stderr, "cyclone_peer: cannot read dump %s\n", argv[1]);
    return 1;
  }
  options_t o;
  if (!parse_options(argc, argv, &o)) return 2;
  endpoints_t e;
  if (!create_endpoints(o.domain, &e)) return 1;
  if (!wait_matched_and_go(&e, o.go_file)) {
    dds_delete(e.pp);
    return 1;
  }

  tally_t t;
  memset(&t, 0, sizeof(t));
  replay_t r;
  memset(&r, 0, sizeof(r));
  r.o = &o;
  r.e = &e;
  r.imu_defect = -1;
  r.last_plain = -1.0;
  replay(f, &r, &t);
  fclose(f);
  wait_for_last_odometry(&e, o.wait_s, r.last_plain, &t);
  print_results(&r, &t);
  free(t.stamps);
  dds_delete(e.pp);
  return 0;
}
