// Compiles the portable BVH records as C++ so their static_asserts on size and offsets always run.
#include "bvh/bvh_layout.h"
