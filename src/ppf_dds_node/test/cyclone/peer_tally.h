/* What cyclone_peer receives from the node (rt/odometry, rt/skeleton_planes), checked and counted
 * for its RESULT line. */
#pragma once

#include "dds/dds.h"

typedef struct {
  int odom, odom_bad, odom_frames_bad, odom_not_monotonic, planes, planes_bad, planes_total;
  double last_odom_stamp;
  double* stamps; /* every odometry stamp received, for the hostile checks */
  int n_stamps, cap_stamps;
} tally_t;

/* Takes everything both readers hold and counts it into *t: odometry with a non-finite value or
 * a non-unit quaternion, frames other than odom/base_link, stamps that do not increase; plane
 * arrays in another frame or with a non-finite offset or non-unit normal. */
void drain(dds_entity_t odom_reader, dds_entity_t planes_reader, tally_t* t);

/* Odometry for the scan stamped s (header at scan start, 10 Hz): stamped at the scan's last
 * point, s + ~0.1 s; the scan before ends just before s, the next one at s + ~0.2 s. */
int odom_for(const tally_t* t, double s);
