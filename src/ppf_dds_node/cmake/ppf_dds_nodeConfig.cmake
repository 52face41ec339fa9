# find_package(ppf_dds_node): ppf_dds_node::ppf_node_config, the node config's schema and loader
# (a static library; the node's executables are not targets to link).
include(CMakeFindDependencyMacro)
find_dependency(ppf_core)
find_dependency(fastrtps)
find_dependency(yaml-cpp)
find_dependency(ppf_trajectory)
include("${CMAKE_CURRENT_LIST_DIR}/ppf_dds_nodeTargets.cmake")
