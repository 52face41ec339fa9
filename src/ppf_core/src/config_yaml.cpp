#include "ppf_core/config_yaml.hpp"
