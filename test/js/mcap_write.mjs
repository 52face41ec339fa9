#!/usr/bin/env node
// Independent MCAP writer for ppf_bag tests: writes OUT with @mcap/core (profile "ros2"), one
// channel /imu of sensor_msgs/msg/Imu (schema encoding ros2msg, message encoding cdr) with
// --count messages (default 5) serialized by @foxglove/rosmsg2-serialization.
// Options: --compression none|lz4|zstd (default none), --no-chunks, --chunk-size BYTES.
// Message i: stamp {sec: 1700000000+i, nanosec: 250000000}, frame_id "imu_link",
// orientation (0,0,0,1), orientation_covariance[k] = k*0.5, angular_velocity (0.25*i, -0.5, 1.5),
// angular_velocity_covariance all 0, linear_acceleration (0.125, 0, 9.75+i),
// linear_acceleration_covariance[0] = -1 (rest 0); log_time = publish_time = stamp in ns.
import { open } from "node:fs/promises";
import { McapWriter } from "@mcap/core";
import { parse } from "@foxglove/rosmsg";
import { MessageWriter } from "@foxglove/rosmsg2-serialization";
import lz4 from "lz4js";
import zstd from "@foxglove/wasm-zstd";

// Written out here (not taken from ppf_bag) so this writer stays independent of the code under test.
const IMU_DEFINITION = `std_msgs/Header header
geometry_msgs/Quaternion orientation
float64[9] orientation_covariance
geometry_msgs/Vector3 angular_velocity
float64[9] angular_velocity_covariance
geometry_msgs/Vector3 linear_acceleration
float64[9] linear_acceleration_covariance
================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
================================================================================
MSG: geometry_msgs/Quaternion
float64 x 0
float64 y 0
float64 z 0
float64 w 1
================================================================================
MSG: geometry_msgs/Vector3
float64 x
float64 y
float64 z
`;

const args = process.argv.slice(2);
const opt = (name, dflt) => {
  const i = args.indexOf(name);
  return i >= 0 ? args[i + 1] : dflt;
};
const out = args[0];
if (!out || out.startsWith("--")) {
  console.error("usage: mcap_write.mjs OUT [--compression none|lz4|zstd] [--no-chunks] [--count N] [--chunk-size B]");
  process.exit(2);
}
const compression = opt("--compression", "none");
const count = Number(opt("--count", "5"));
const chunkSize = Number(opt("--chunk-size", String(1024 * 1024)));
const useChunks = !args.includes("--no-chunks");

await zstd.isLoaded;
let compressChunk;
if (compression === "lz4") {
  compressChunk = (data) => ({ compression: "lz4", compressedData: Uint8Array.from(lz4.compress(data)) });
} else if (compression === "zstd") {
  compressChunk = (data) => ({ compression: "zstd", compressedData: zstd.compress(data, 3) });
} else if (compression !== "none") {
  console.error(`unknown compression ${compression}`);
  process.exit(2);
}

const fh = await open(out, "w");
let pos = 0n;
const writable = {
  write: async (buf) => {
    await fh.write(buf);
    pos += BigInt(buf.byteLength);
  },
  position: () => pos,
};
const writer = new McapWriter({ writable, useChunks, chunkSize, compressChunk });
await writer.start({ profile: "ros2", library: "mcap_write.mjs" });
const schemaId = await writer.registerSchema({
  name: "sensor_msgs/msg/Imu",
  encoding: "ros2msg",
  data: new TextEncoder().encode(IMU_DEFINITION),
});
const channelId = await writer.registerChannel({
  topic: "/imu",
  schemaId,
  messageEncoding: "cdr",
  metadata: new Map([["offered_qos_profiles", ""]]),
});
const imu = new MessageWriter(parse(IMU_DEFINITION, { ros2: true }));
for (let i = 0; i < count; ++i) {
  const msg = {
    header: { stamp: { sec: 1700000000 + i, nanosec: 250000000 }, frame_id: "imu_link" },
    orientation: { x: 0, y: 0, z: 0, w: 1 },
    orientation_covariance: Array.from({ length: 9 }, (_, k) => k * 0.5),
    angular_velocity: { x: 0.25 * i, y: -0.5, z: 1.5 },
    angular_velocity_covariance: new Array(9).fill(0),
    linear_acceleration: { x: 0.125, y: 0, z: 9.75 + i },
    linear_acceleration_covariance: [-1, 0, 0, 0, 0, 0, 0, 0, 0],
  };
  const t = BigInt(1700000000 + i) * 1000000000n + 250000000n;
  await writer.addMessage({ channelId, sequence: i, logTime: t, publishTime: t, data: imu.writeMessage(msg) });
}
await writer.end();
await fh.close();
