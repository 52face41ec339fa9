#include "ppf_core/evaluation.hpp"
