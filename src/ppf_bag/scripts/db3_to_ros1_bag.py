#!/usr/bin/python3
"""Converts the PointCloud2 and Imu topics of a rosbag2 .db3 file to a ROS 1 bag with Debian's
rosbag, decoding the CDR here (independently of ppf_bag): the test that ppf_offline gives the same
trajectory on the ROS 1 bag as on the rosbag2 original.

usage: db3_to_ros1_bag.py IN.db3 OUT.bag none|bz2|lz4
"""
import sqlite3
import struct
import sys

import rosbag
import rospy
import sensor_msgs.msg


class Cdr:
    """XCDR1 reader; alignment counts from the end of the 4-byte encapsulation header."""

    def __init__(self, data):
        if data[0:2] != b"\x00\x01":
            raise ValueError("not little-endian CDR")
        self.b, self.p = data, 4

    def _get(self, fmt, size):
        self.p += (-(self.p - 4)) % size
        v = struct.unpack_from("<" + fmt, self.b, self.p)[0]
        self.p += size
        return v

    def u8(self):
        v = self.b[self.p]
        self.p += 1
        return v

    def u32(self):
        return self._get("I", 4)

    def i32(self):
        return self._get("i", 4)

    def f64(self):
        return self._get("d", 8)

    def string(self):
        n = self.u32()
        s = self.b[self.p:self.p + n - 1].decode()
        self.p += n
        return s

    def header(self, h):
        h.stamp = rospy.Time(self.i32(), self.u32())
        h.frame_id = self.string()


def cloud(data):
    c, m = Cdr(data), sensor_msgs.msg.PointCloud2()
    c.header(m.header)
    m.height, m.width = c.u32(), c.u32()
    for _ in range(c.u32()):
        name = c.string()
        offset = c.u32()
        datatype = c.u8()
        m.fields.append(sensor_msgs.msg.PointField(name=name, offset=offset, datatype=datatype,
                                                   count=c.u32()))
    m.is_bigendian = bool(c.u8())
    m.point_step, m.row_step = c.u32(), c.u32()
    n = c.u32()
    m.data = bytes(c.b[c.p:c.p + n])
    c.p += n
    m.is_dense = bool(c.u8())
    return m


def imu(data):
    c, m = Cdr(data), sensor_msgs.msg.Imu()
    c.header(m.header)
    v = [c.f64() for _ in range(37)]
    m.orientation.x, m.orientation.y, m.orientation.z, m.orientation.w = v[0:4]
    m.orientation_covariance = v[4:13]
    m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z = v[13:16]
    m.angular_velocity_covariance = v[16:25]
    m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z = v[25:28]
    m.linear_acceleration_covariance = v[28:37]
    return m


def main():
    src, out, compression = sys.argv[1:4]
    db = sqlite3.connect(src)
    topics = {tid: (name, typ) for tid, name, typ in db.execute("SELECT id, name, type FROM topics")}
    convert = {"sensor_msgs/msg/PointCloud2": cloud, "sensor_msgs/msg/Imu": imu}
    n = 0
    with rosbag.Bag(out, "w", compression=compression) as bag:
        for tid, t, data in db.execute(
                "SELECT topic_id, timestamp, data FROM messages ORDER BY timestamp, id"):
            name, typ = topics[tid]
            if typ in convert:
                bag.write(name, convert[typ](data), rospy.Time(t // 10**9, t % 10**9))
                n += 1
    print("wrote %d messages to %s" % (n, out))


if __name__ == "__main__":
    main()
