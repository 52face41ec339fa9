// Compile-time facts about each ROS 2 message type we speak: its generated DDS type support, its
// ROS name (as rosbag2 and `ros2 topic` write it) and its DDS type name (what goes on the wire).
#pragma once

#include "builtin_interfaces/msg/TimePubSubTypes.h"
#include "geometry_msgs/msg/PoseStampedPubSubTypes.h"
#include "geometry_msgs/msg/TransformStampedPubSubTypes.h"
#include "nav_msgs/msg/OdometryPubSubTypes.h"
#include "nav_msgs/msg/PathPubSubTypes.h"
#include "ppf_msgs/msg/SkeletonPlaneArrayPubSubTypes.h"
#include "sensor_msgs/msg/ImuPubSubTypes.h"
#include "sensor_msgs/msg/PointCloud2PubSubTypes.h"
#include "std_msgs/msg/HeaderPubSubTypes.h"
#include "tf2_msgs/msg/TFMessagePubSubTypes.h"

namespace ppf::msgs {

template <typename MsgT>
struct MsgTraits;  // only the specializations below exist: a missing one is a compile error

#define PPF_MSGS_TRAITS(PKG, NAME)                                          \
  template <>                                                               \
  struct MsgTraits<PKG::msg::NAME> {                                        \
    using PubSubType = PKG::msg::NAME##PubSubType;                          \
    static constexpr const char* kRosName = #PKG "/msg/" #NAME;             \
    static constexpr const char* kDdsName = #PKG "::msg::dds_::" #NAME "_"; \
  };

PPF_MSGS_TRAITS(builtin_interfaces, Time)
PPF_MSGS_TRAITS(std_msgs, Header)
PPF_MSGS_TRAITS(sensor_msgs, PointCloud2)
PPF_MSGS_TRAITS(sensor_msgs, Imu)
PPF_MSGS_TRAITS(geometry_msgs, PoseStamped)
PPF_MSGS_TRAITS(geometry_msgs, TransformStamped)
PPF_MSGS_TRAITS(nav_msgs, Odometry)
PPF_MSGS_TRAITS(nav_msgs, Path)
PPF_MSGS_TRAITS(tf2_msgs, TFMessage)
PPF_MSGS_TRAITS(ppf_msgs, SkeletonPlaneArray)

#undef PPF_MSGS_TRAITS

}  // namespace ppf::msgs
