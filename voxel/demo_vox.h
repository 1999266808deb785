// demo_vox.h: the demo world's MagicaVoxel asset, written by voxshadow itself.
#ifndef VOXSHADOW_DEMO_VOX_H
#define VOXSHADOW_DEMO_VOX_H

#include "voxel/vox_writer.h"

namespace vs {

// A stack of crates beside a signpost: two models (a 5^3 crate, odd-sized, and a 4 x 1 x 9 post with its sign)
// and a scene graph of four shapes, two of them rotated, one nested in a subgroup. Preconditions: none.
VoxWriteFile demoCratesVox();

}  // namespace vs

#endif
