// vulkan_lighting.h: the deferred lighting pass on a Vulkan device (lighting/shaders/deferred_lighting.comp),
// the shader build of lighting/shared/shading.h; shadeOnCpu (lighting/deferred.h) is its C++ build.
#ifndef VOXSHADOW_VULKAN_LIGHTING_H
#define VOXSHADOW_VULKAN_LIGHTING_H

#include <functional>
#include <memory>
#include <span>
#include <utility>

#include "compute/vulkan/vulkan_context.h"
#include "compute/vulkan/vulkan_tracer.h"
#include "lighting/deferred.h"
#include "lighting/evsm.h"
#include "lighting/vulkan_shadows.h"

namespace vs {

struct HostGBuffer;  // lighting/host_gbuffer.h

// What the pass did in one call: bytes moved between host and device memory, pixels shaded and dispatches.
struct LightingTraffic {
  std::uint64_t uploaded = 0;
  std::uint64_t readBack = 0;
  std::uint64_t pixelsShaded = 0;
  std::uint64_t momentTexels = 0;  // EVSM moments computed (the whole store where the pass held none)
  int dispatches = 0;
};

// What changed in a frame's lighting inputs since the last pass.
struct ShadeChanges {
  // Ranges [first, first + count) of ShadeInputs::shadowTexels that may differ.
  std::span<const std::pair<std::size_t, std::size_t>> texelRanges;
  // Row-major pixels, each at most once, whose G-buffer texel or visibility answers may differ or whose colour
  // may change for another reason (a shadow lookup of a changed texel): these are read back.
  std::span<const std::uint32_t> pixels;
  // Of `pixels`, those whose G-buffer texel or visibility answers may differ: only theirs are written (the
  // others are shaded again because a shadow lookup reads a changed texel). Row-major, each at most once.
  std::span<const std::uint32_t> inputPixels;
  // Every pixel instead of `pixels` (the camera moved, a light changed): the whole G-buffer and visibility
  // answers are written and every colour read back, while the layer store is still written only where
  // texelRanges say, since it is what a frame that only moved the camera keeps.
  bool allPixels = false;
  // The pass's layer store already holds this frame's texels (traced into storeTarget() on the device):
  // nothing of ShadeInputs::shadowTexels is written, which may then be stale. Precondition: holdsStore() of
  // the frame's store size; texelRanges empty.
  bool storeInPlace = false;
  // Whether the shaded pixels' colours and terms are copied into `out` (which then holds the last frame's
  // whole colour, or terms); when false that part of `out` is left as it is.
  bool readColor = true;
  bool readTerms = true;
  // The pass's G-buffer holds this frame's texels, resolved on the device (resolveGBuffer): none is written from
  // `gbuffer` (where the pass holds no whole G-buffer of this size, `gbuffer` goes up whole).
  bool gbufferOnDevice = false;
  // Likewise the answers per pixel and light, spread on the device (spreadVisibility).
  bool visibilityOnDevice = false;
  // EVSM: the moment rectangles the changed texels touch (null: none), computed from the pass's store before it
  // shades; and the whole store's work, for a pass that holds no moments of this frame's size (its first, or
  // after another size): called only then.
  const MomentWork* moments = nullptr;
  std::function<MomentWork()> wholeMoments;
};

class VulkanLighting {
 public:
  // Prepares the pass on `context`'s device, which it keeps alive. The lighting shader has variants
  // (lighting/lighting_variant.h): a general one that serves every frame, and one per frame shape (the kinds,
  // filters and view counts of up to gpu::VS_LIGHTING_SPECIALIZED_LIGHTS lights, the debug and shadow modes)
  // holding only the code those lights run, which a CPU device (llvmpipe) needs to skip the rest (1.6x faster
  // on the demo frame on lavapipe). With `specialize`, a shape's variant is compiled once
  // kCallsBeforeSpecializing calls in a row asked for it, and used from then on while it is among the 8 most
  // recently used; every variant gives the general shader's bits. The pipelines are compiled once per device
  // and shared by every VulkanLighting on it (VulkanContext::shared): the general shader here, by the first
  // pass on the device.
  explicit VulkanLighting(std::shared_ptr<VulkanContext> context, bool specialize = true);
  // Lighting shader variants compiled so far on this pass's device, the general one included.
  int variantsCompiled() const;

  // A frame shape is specialised once this many calls in a row asked for it: a variant costs a compile (about
  // two seconds on llvmpipe, more than it saves on one 720p frame), which pays back only over the frames of a
  // loop that keeps its lights. Until then, and for shapes that change every few frames, the general shader
  // shades.
  static constexpr int kCallsBeforeSpecializing = 8;
  ~VulkanLighting();

  // The pass over one frame: the same inputs and results as shadeOnCpu. Buffers grow as frames need and are
  // kept for the next frame. `moments`: the whole moment store's work (momentWork over wholeMomentRects), run
  // on the device before the frame is shaded; required when inputs.momentTexels > 0 (inputs.moments is not
  // read). Throws vs::Error(BadInput) as shadeOnCpu does, vs::Error(Runtime) on device errors.
  // `readColor`, `readTerms`: whether the colours and terms are copied back (else the output's are empty).
  // `gbufferOnDevice`, `visibilityOnDevice`: as ShadeChanges' members.
  ShadeOutput shade(const ShadeInputs& inputs, const gpu::ShadePush& push, const GBuffer& gbuffer,
                    std::span<const std::uint32_t> rayVisibility, LightingTraffic* traffic = nullptr,
                    const MomentWork* moments = nullptr, bool readColor = true, bool readTerms = true,
                    bool gbufferOnDevice = false, bool visibilityOnDevice = false);

  // The pass over a frame whose inputs differ from the last shade()'s or shadeChanged()'s only where `changes`
  // says: the buffers keep the last frame's inputs, so only the changed texel ranges and pixels (their G-buffer
  // texels and visibility answers) are written, and only those pixels' colours and terms are read back into
  // `out`, which holds the last frame's results. Only the listed pixels are shaded again (one invocation each)
  // unless they are most of the frame or allPixels is set; every other pixel keeps the colour and terms the
  // buffers hold, which are its own, since its inputs did not change.
  // Preconditions: the same sizes as the last call (pixels, lights, views, texels, visibility answers), the
  // views', lights' and push's records may differ (they are written whole); a caller that cannot say what
  // changed calls shade(). When the buffers do not hold a last frame of these sizes (none yet, or replaced),
  // everything is written and read back, as shade() does. Throws as shade() does.
  void shadeChanged(const ShadeInputs& inputs, const gpu::ShadePush& push, const GBuffer& gbuffer,
                    std::span<const std::uint32_t> rayVisibility, const ShadeChanges& changes, ShadeOutput& out,
                    LightingTraffic* traffic = nullptr);

  // Resolves a camera trace's hits on this pass's device (VulkanTracer::lastCameraTrace, called right after
  // traceCamera, of the tracer on this device) into the pass's G-buffer, with vsResolveHit and the scene's tables
  // (gbufferTables; written only when they differ from the last call's): the frame's G-buffer reaches the
  // lighting pass without crossing from the host, and shade() or shadeChanged() with gbufferOnDevice write none.
  // A trace of listed pixels updates those texels; where the pass holds no whole G-buffer of this size for them
  // to update, `current` (the host's G-buffer after this trace, the same bits: resolveGBuffer of the same hits)
  // goes up whole instead. Throws vs::Error(BadInput) when the trace holds no hits, more than the frame's
  // pixels, or `current` is not width x height texels; vs::Error(Runtime) on device errors.
  void resolveGBuffer(const CameraTraceBuffers& trace, const GBufferTables& tables, const GBuffer& current,
                      LightingTraffic* traffic = nullptr);
  // Spreads a visibility trace's answers on this pass's device (VulkanTracer::lastVisibilityTrace, right after
  // a traceVisibility from DeviceReceivers) into the pass's answers per pixel and light (1 where clear): light l
  // of the frame is the trace's light slots[l], or has no ray (-1: its answer is 1). `current`: the host's
  // answers after this trace, pixels x lights (the same values), written whole instead where the trace holds no
  // results on the device or would update rows the pass does not hold whole. Then shade() or shadeChanged()
  // with visibilityOnDevice write none. Throws vs::Error(BadInput) on sizes that disagree.
  void spreadVisibility(const VisibilityTraceBuffers& trace, std::span<const int> slots, std::size_t pixels,
                        std::span<const std::uint32_t> current, LightingTraffic* traffic = nullptr);
  // Makes the pass's G-buffer, and the visibility receivers beside it, from a host engine's G-buffer images on
  // this pass's device (lighting/host_gbuffer.h, read with vsImportTexel), for a frame of width x height pixels:
  // then shade() or shadeChanged() with gbufferOnDevice write none, and receivers() serves a visibility trace.
  // Throws vs::Error(BadInput) as hostGBufferRecord does, and for an image whose layout is not one the pass reads
  // from or whose format the device cannot sample as floats (naming the field); vs::Error(Runtime) on device
  // errors.
  void importGBuffer(const HostGBuffer& host, int width, int height, LightingTraffic* traffic = nullptr);
  // The visibility receivers of the G-buffer the pass holds (vsReceiverOf each texel), which the resolve writes
  // beside it, for VulkanTracer::traceVisibility to read in place (set `pixels` of the result to take some);
  // an empty buffer where they are not whole for `pixels` pixels (a G-buffer written from the host since).
  DeviceReceivers receivers(std::size_t pixels) const;
  // Copies the answers per pixel and light the pass holds (spread or written) into `out`, whose size must be
  // the held one's (else vs::Error(BadInput)).
  void readVisibility(std::span<std::uint32_t> out, LightingTraffic* traffic = nullptr) const;
  // Copies the G-buffer the pass holds (resolved or written) into `out`, whose size must be the held one's (else
  // vs::Error(BadInput)).
  void readGBuffer(GBuffer& out, LightingTraffic* traffic = nullptr) const;

  // Whether the pass's layer store holds a whole store of `texels` texels from the last completed pass (and
  // whatever was traced into it since): a frame may then trace into it in place (storeTarget) and shade with
  // ShadeChanges::storeInPlace.
  bool holdsStore(std::size_t texels) const;
  // The layer store's device buffer (floats, ShadeInputs::shadowTexels' layout) for VulkanTracer::traceInto.
  // Precondition: holdsStore(texels); else vs::Error(Runtime).
  VkBuffer storeTarget(std::size_t texels) const;
  // Copies the store's texels to `out` (as long as the held store, else vs::Error(BadInput)): a host copy,
  // asked for by a caller, of layers that stayed on the device. Adds the bytes to traffic->readBack.
  void readStore(std::span<float> out, LightingTraffic* traffic = nullptr) const;
  // Writes ranges [first, first + count) of `store` (ShadeInputs::shadowTexels' layout) into the held layer
  // store: texels traced since the pass last ran. Precondition: holdsStore(store.size()) (else
  // vs::Error(BadInput)); each range inside it.
  void writeStore(std::span<const float> store, std::span<const std::pair<std::size_t, std::size_t>> ranges,
                  LightingTraffic* traffic = nullptr);
  // The held frame's buffers for a host's shader (lighting/vulkan_shadows.h), after a memory barrier on the
  // queue that makes every earlier write visible to later submissions. Precondition: the pass holds a whole
  // frame of `width` x `height` pixels (else vs::Error(Runtime)).
  VulkanShadows shadows(int width, int height) const;
  // Copies the held frame's whole colour and shadow terms (each left out where its output is null), as
  // shade() gives them, adding the bytes to traffic->readBack. Precondition: the pass holds a whole frame
  // (else vs::Error(Runtime)).
  void readResults(std::vector<glm::vec4>* color, std::vector<float>* terms, LightingTraffic* traffic = nullptr) const;
  // Copies the moment store (ShadeInputs::moments' layout) to `out`, as long as the held one (else
  // vs::Error(BadInput)).
  void readMoments(std::span<glm::vec4> out, LightingTraffic* traffic = nullptr) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace vs

#endif
