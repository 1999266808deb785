// evsm_pass.h: the moment pass (DESIGN.md §7): a layer's EVSM moments computed from its depths and
// box-blurred, separably, over rectangles of it (EvsmJob). One source: the shader
// lighting/shaders/evsm_moments.comp runs it per invocation, lighting/evsm.cpp per texel on the CPU, and the
// sums run in one order in both, so the moments are the same bits.
//
// The includer provides, as arrays or buffer members of these names: shadowTexels[i] (float, the layer store),
// evsmViews[i] (EvsmView), evsmJobs[i] (EvsmJob), evsmBorder[i] (int); and the functions vsLoadScratch(i),
// vsStoreScratch(i, m) (the horizontal pass's sums) and vsStoreMoments(i, m) (the moment store), over storage
// of its choice (the shader keeps each in two vec2 buffers, the positive and the negative warp's, so that a
// buffer stays within a device's maxStorageBufferRange twice as long). It includes lighting/shared/evsm.h
// first.
#ifndef VOXSHADOW_EVSM_PASS_H
#define VOXSHADOW_EVSM_PASS_H

// The layer-store index of window texel (x, y) of view v, for x and y in [-r, N + r): inside the window, its
// (ring) place; past a cube face's edge, the texel of the neighbouring face that holds the same direction
// (evsmBorder, made on the host in double), so a face blurs across its edges as the cube is one surface; past
// any other layer's edge, the edge texel (nothing is known beyond a window).
int vsEvsmSource(VS_IN(EvsmView) v, int x, int y) {
  int n = v.layer.y;
  int r = v.layer.w;
  bool inside = x >= 0 && y >= 0 && x < n && y < n;
  if (!inside && v.place.z >= 0) {
    // The border map: the r rows above, the r rows below (each N + 2r wide), then per inner row r texels on
    // the left and r on the right.
    int w = n + 2 * r;
    int k;
    if (y < 0) k = (y + r) * w + (x + r);
    else if (y >= n) k = r * w + (y - n) * w + (x + r);
    else k = 2 * r * w + y * 2 * r + (x < 0 ? x + r : r + (x - n));
    return evsmBorder[v.place.z + k];
  }
  int cx = clamp(x, 0, n - 1);
  int cy = clamp(y, 0, n - 1);
  return v.layer.x + ((cy + v.place.y) & (n - 1)) * n + ((cx + v.place.x) & (n - 1));
}

// The job that invocation i of a pass belongs to: the last whose first invocation (info.y horizontal, info.z
// vertical) is at most i.
int vsEvsmJobOf(int invocation, int jobCount, int pass) {
  int lo = 0;
  int hi = jobCount - 1;
  while (lo < hi) {
    int mid = (lo + hi + 1) / 2;
    int first = pass == 0 ? evsmJobs[mid].info.y : evsmJobs[mid].info.z;
    if (first <= invocation) lo = mid;
    else hi = mid - 1;
  }
  return lo;
}

// Horizontal pass: invocation i of the pass sums the moments of 2r + 1 texels along its row (left to right)
// and scales the sum, into its job's scratch. A job's scratch holds its rows y0 - r .. y1 + r.
void vsEvsmHorizontal(int invocation, int jobCount) {
  EvsmJob job = evsmJobs[vsEvsmJobOf(invocation, jobCount, 0)];
  EvsmView v = evsmViews[job.info.x];
  int r = v.layer.w;
  int width = job.rect.z - job.rect.x;
  int local = invocation - job.info.y;
  int x = job.rect.x + local % width;
  int y = job.rect.y - r + local / width;
  VS_PRECISE vec4 sum = vec4(0.0f);
  for (int d = -r; d <= r; ++d) sum += vsEvsmWarp(shadowTexels[vsEvsmSource(v, x + d, y)], v.warp.z, vec2(v.warp.x, v.warp.y));
  VS_PRECISE vec4 mean = sum * v.warp.w;
  vsStoreScratch(job.info.w + local, mean);
}

// Vertical pass: invocation i sums 2r + 1 of the horizontal sums down its column (top to bottom), scales, and
// stores the moments at the texel's ring place.
void vsEvsmVertical(int invocation, int jobCount) {
  EvsmJob job = evsmJobs[vsEvsmJobOf(invocation, jobCount, 1)];
  EvsmView v = evsmViews[job.info.x];
  int r = v.layer.w;
  int n = v.layer.y;
  int width = job.rect.z - job.rect.x;
  int local = invocation - job.info.z;
  int col = local % width;
  int row = local / width;  // from y0; the scratch starts r rows above
  VS_PRECISE vec4 sum = vec4(0.0f);
  for (int d = 0; d <= 2 * r; ++d) sum += vsLoadScratch(job.info.w + (row + d) * width + col);
  VS_PRECISE vec4 mean = sum * v.warp.w;
  int x = job.rect.x + col;
  int y = job.rect.y + row;
  vsStoreMoments(v.layer.z + ((y + v.place.y) & (n - 1)) * n + ((x + v.place.x) & (n - 1)), mean);
}

#endif
