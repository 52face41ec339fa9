#!/usr/bin/python3
"""Writes a ROS 1 bag with Debian's rosbag (the independent writer of test_ros1.cpp).

usage: write_ros1_bag.py OUT.bag none|bz2|lz4 CHUNK_THRESHOLD EXPECTED.json [IMU_COUNT]

IMU_COUNT (default 40) scales the whole sequence; fuzz/corpus/fuzz_bag_ros1 holds bags of 8.

Content is deterministic (fixed seed): PointCloud2 on /points, Imu on /imu, std_msgs/String on
/chatter (a type the reader passes through), and livox_ros_driver(2)/CustomMsg on /livox and
/livox2 (classes generated from the .msg text, as no Debian package ships them). One Imu is
written with a time before its predecessor, so the reader must sort. EXPECTED.json lists every
message in write order with its fields (floats as IEEE bit patterns, byte arrays as hex) and the
file offsets of the chunks and of the index section, read back through rosbag.
"""
import json
import random
import struct
import sys

import genpy.dynamic
import rosbag
import rospy
import sensor_msgs.msg
import std_msgs.msg

LIVOX_TEXT = """Header header
uint64 timebase
uint32 point_num
uint8 lidar_id
uint8[3] rsvd
CustomPoint[] points
================================================================================
MSG: std_msgs/Header
uint32 seq
time stamp
string frame_id
================================================================================
MSG: {pkg}/CustomPoint
uint32 offset_time
float32 x
float32 y
float32 z
uint8 reflectivity
uint8 tag
uint8 line
"""


def livox_classes(pkg):
    core = pkg + "/CustomMsg"
    classes = genpy.dynamic.generate_dynamic(core, LIVOX_TEXT.format(pkg=pkg))
    return classes[core], classes[pkg + "/CustomPoint"]


def f64(rng):
    # Exact in binary and in JSON: multiples of 1/1024.
    return rng.randint(-100000, 100000) / 1024.0


def main():
    out, compression, threshold, expected_path = sys.argv[1:5]
    imu_count = int(sys.argv[5]) if len(sys.argv) > 5 else 40
    rng = random.Random(15)
    t0 = 1700000000
    records = []
    livox = {p: livox_classes(p) for p in ("livox_ros_driver", "livox_ros_driver2")}
    with rosbag.Bag(out, "w", compression=compression, chunk_threshold=int(threshold)) as bag:
        for i in range(imu_count):
            t_ns = t0 * 10**9 + i * 5000000 + 123
            if i == 17:
                t_ns -= 7000000  # before message 16: out of order within the bag
            imu = sensor_msgs.msg.Imu()
            imu.header.seq = i
            imu.header.stamp = rospy.Time(t0 + i // 10, (i % 10) * 100000000 + 42)
            imu.header.frame_id = "imu_link"
            vals = [f64(rng) for _ in range(37)]
            imu.orientation.x, imu.orientation.y, imu.orientation.z, imu.orientation.w = vals[0:4]
            imu.orientation_covariance = vals[4:13]
            imu.angular_velocity.x, imu.angular_velocity.y, imu.angular_velocity.z = vals[13:16]
            imu.angular_velocity_covariance = vals[16:25]
            imu.linear_acceleration.x, imu.linear_acceleration.y, imu.linear_acceleration.z = \
                vals[25:28]
            imu.linear_acceleration_covariance = vals[28:37]
            bag.write("/imu", imu, rospy.Time(t_ns // 10**9, t_ns % 10**9))
            records.append({"topic": "/imu", "t": t_ns, "kind": "imu",
                            "sec": imu.header.stamp.secs, "nsec": imu.header.stamp.nsecs,
                            "frame": "imu_link", "values": vals})
            if i % 4 == 1:
                k = i // 4
                width = 3 + k
                cloud = sensor_msgs.msg.PointCloud2()
                cloud.header.seq = k
                cloud.header.stamp = rospy.Time(t0 + 1, k * 1000 + 7)
                cloud.header.frame_id = "lidar"
                cloud.height = 1
                cloud.width = width
                names = [("x", 0, 7), ("y", 4, 7), ("z", 8, 7), ("intensity", 12, 7), ("t", 16, 6)]
                cloud.fields = [sensor_msgs.msg.PointField(name=n, offset=o, datatype=d, count=1)
                                for n, o, d in names]
                cloud.is_bigendian = False
                cloud.point_step = 20
                cloud.row_step = 20 * width
                data = bytes(rng.randrange(256) for _ in range(20 * width))
                cloud.data = data
                cloud.is_dense = (k % 2 == 0)
                ct = t_ns + 1000
                bag.write("/points", cloud, rospy.Time(ct // 10**9, ct % 10**9))
                records.append({"topic": "/points", "t": ct, "kind": "cloud",
                                "sec": t0 + 1, "nsec": k * 1000 + 7, "frame": "lidar",
                                "height": 1, "width": width,
                                "fields": [[n, o, d, 1] for n, o, d in names],
                                "is_bigendian": 0, "point_step": 20, "row_step": 20 * width,
                                "data": data.hex(), "is_dense": int(cloud.is_dense)})
            if i % 10 == 3:
                s = std_msgs.msg.String(data="hello %d" % i)
                st = t_ns + 2000
                bag.write("/chatter", s, rospy.Time(st // 10**9, st % 10**9))
                raw = struct.pack("<I", len(s.data)) + s.data.encode()
                records.append({"topic": "/chatter", "t": st, "kind": "raw",
                                "type": "std_msgs/String", "data": raw.hex()})
            if i % 10 == 5:
                for topic, pkg in (("/livox", "livox_ros_driver"), ("/livox2", "livox_ros_driver2")):
                    msg_cls, point_cls = livox[pkg]
                    m = msg_cls()
                    m.header.seq = i
                    m.header.stamp = rospy.Time(t0 + 2, 5)  # not the timebase: must be replaced
                    m.header.frame_id = "livox_frame"
                    m.timebase = (t0 + 1) * 10**9 + 250000000 + i
                    m.lidar_id = 1
                    m.rsvd = [0, 0, 0]
                    pts = []
                    for _ in range(4 + i // 10):
                        pts.append((rng.randrange(10**8), f64(rng), f64(rng), f64(rng),
                                    rng.randrange(256), rng.randrange(256), rng.randrange(6)))
                    m.points = []
                    for (ot, x, y, z, refl, tag, line) in pts:
                        cp = point_cls()
                        cp.offset_time, cp.x, cp.y, cp.z = ot, x, y, z
                        cp.reflectivity, cp.tag, cp.line = refl, tag, line
                        m.points.append(cp)
                    m.point_num = len(pts)
                    lt = t_ns + 3000 + (1 if pkg.endswith("2") else 0)
                    bag.write(topic, m, rospy.Time(lt // 10**9, lt % 10**9))
                    records.append({"topic": topic, "t": lt, "kind": "livox",
                                    "timebase": m.timebase, "frame": "livox_frame",
                                    "points": [list(p) for p in pts]})
    with rosbag.Bag(out) as bag:
        chunks = [ci.pos for ci in bag._chunks]
        index_pos = bag._index_data_pos
    with open(expected_path, "w") as f:
        json.dump({"messages": records, "chunks": chunks, "index_pos": index_pos}, f)


if __name__ == "__main__":
    main()
