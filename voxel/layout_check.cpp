// Compiles the portable brickmap records as C++ so their static_asserts on size and offsets always run.
#include "voxel/brickmap_layout.h"
