# find_package(ppf_config): where the installed configuration files are.
get_filename_component(ppf_config_SHARE_DIR "${CMAKE_CURRENT_LIST_DIR}/.." ABSOLUTE)
if(NOT EXISTS "${ppf_config_SHARE_DIR}/reference.yaml")
  set(ppf_config_FOUND FALSE)
  set(ppf_config_NOT_FOUND_MESSAGE "no reference.yaml in ${ppf_config_SHARE_DIR}")
endif()
