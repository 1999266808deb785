// Compiles the portable trace records as C++ so their static_asserts on size and offsets always run.
#include "compute/shared/trace_rays.h"
#include "compute/shared/trace_view.h"
