/* The dump file cyclone_peer replays (format in cyclone_peer.c's header comment): one record at a
 * time, decoded into the Cyclone-generated message types. */
#pragma once

#include <stdint.h>
#include <stdio.h>

#include "ros2_types.h"

typedef sensor_msgs_msg_dds__PointCloud2_ cloud_t;
typedef sensor_msgs_msg_dds__Imu_ imu_t;

/* What every record starts with; frame is malloc'ed (the caller frees it). */
typedef struct {
  uint8_t kind; /* 1 imu, 2 cloud */
  int64_t bag_ns;
  int32_t sec;
  uint32_t nsec;
  char* frame;
} record_head_t;

/* Opens the dump and checks its magic; NULL if it cannot be read. */
FILE* dump_open(const char* path);

/* The next record's head; 0 at the end of the dump or on a short read. */
int dump_read_head(FILE* f, record_head_t* h);

/* The rest of an IMU record into *m (stamp from h, frame_id borrowed from h); 0 on a short read. */
int dump_read_imu(FILE* f, const record_head_t* h, imu_t* m);

/* The rest of a cloud record into *m (stamp from h, frame_id borrowed from h), its fields and data
 * malloc'ed: dump_free_cloud releases them. 0 on a short read or more than 64 fields (nothing is
 * left allocated then). */
int dump_read_cloud(FILE* f, const record_head_t* h, cloud_t* m);

void dump_free_cloud(cloud_t* m);
