/* Counting and checking what cyclone_peer receives (see peer_tally.h). */
#include "peer_tally.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "ros2_types.h"

static int finite_n(const double* v, int n) {
  for (int i = 0; i < n; ++i)
    if (!isfinite(v[i])) return 0;
  return 1;
}

void drain(dds_entity_t odom_reader, dds_entity_t planes_reader, tally_t* t) {
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

int odom_for(const tally_t* t, double s) {
  for (int i = 0; i < t->n_stamps; ++i)
    if (t->stamps[i] > s + 0.05 && t->stamps[i] < s + 0.15) return 1;
  return 0;
}
