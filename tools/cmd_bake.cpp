// voxshadow bake: scene -> light views -> shadow trace -> EXR + sidecar (+ PNG preview).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>

#include <unistd.h>

#include "compute/tracer.h"
#include "compute/vulkan/vulkan_tracer.h"
#include "compute/cpu/cpu_tracer.h"
#include "lighting/deferred.h"
#include "lighting/evsm.h"
#include "lighting/scene.h"
#include "tools/atomic_file.h"
#include "tools/resources.h"
#include "tools/bake_output.h"
#include "tools/bake_shards.h"
#include "tools/commands.h"
#include "tools/file_kind.h"
#include "tools/progress.h"
#include "voxel/error.h"

namespace vs::cli {

namespace fs = std::filesystem;

std::pair<int, int> parseShard(const std::string& text);

namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

// Rows traced per call, so the progress bar moves within a large view; each call still spans many tiles.
constexpr int kRowsPerBand = 64;

// One view at a time, in bands of rows: the CPU backend's progress moves within a view.
std::vector<ShadowLayer> traceInBands(const Scene& scene, const std::vector<LightView>& views, Tracer& tracer) {
  std::uint64_t totalRows = 0, doneRows = 0;
  for (const LightView& v : views) totalRows += std::uint64_t(v.trace.info.y);
  Progress progress("tracing");
  std::vector<ShadowLayer> layers(views.size());
  tracer.setScene(scene.data());
  for (std::size_t i = 0; i < views.size(); ++i) {
    gpu::TraceView band = views[i].trace;
    const glm::ivec4 whole = band.rect;
    std::vector<ShadowLayer> one(1);
    for (int y0 = whole.y; y0 < whole.w; y0 += kRowsPerBand) {
      band.rect = glm::ivec4(whole.x, y0, whole.z, std::min(whole.w, y0 + kRowsPerBand));
      tracer.traceShadow(std::span<const gpu::TraceView>(&band, 1), one);
      doneRows += std::uint64_t(band.rect.w - band.rect.y);
      progress.update(doneRows, totalRows);
    }
    layers[i] = std::move(one[0]);
  }
  progress.finish();
  return layers;
}

// What the Vulkan trace measured, for --stats.
struct VulkanBakeStats {
  std::string device;
  PipelineStats pipeline;
  std::size_t dispatchCalls = 0;
  bool boxTable = false;          // the shader walked the box table (else the brickmap hierarchy)
  std::vector<double> viewGpuMs;  // per view; < 0 when the device has no timestamps
  double wallMs = 0.0;
};

// Largest image array one trace call fills: big enough that a bake of many views needs few submissions, small
// enough that the image and its readback stay a modest share of any device's memory.
constexpr std::uint64_t kBatchBytes = 1ull << 30;

std::uint64_t layerBytes(const LightView& v) {
  return std::uint64_t(v.trace.info.x) * std::uint64_t(v.trace.info.y) * sizeof(float);
}

std::string lightPath(const Scene& scene, const LightView& v) {
  return scene.desc().file.string() + ": lights[" + std::to_string(v.lightIndex) + "].shadow.resolution";
}

// Views of one size per batch, at most the device's array layers and about kBatchBytes per batch.
std::size_t viewsPerBatch(const VulkanDeviceInfo& info, const LightView& v) {
  std::uint64_t fit = std::max<std::uint64_t>(1, kBatchBytes / layerBytes(v));
  return std::size_t(std::min<std::uint64_t>(fit, std::max<std::uint32_t>(1, info.maxImageArrayLayers)));
}

// Refuses, before any trace, a view the device cannot hold (one layer and its readback).
void checkDeviceFits(const Scene& scene, const std::vector<LightView>& views, const VulkanDeviceInfo& info) {
  for (const LightView& v : views) {
    const std::uint64_t bytes = layerBytes(v);
    if (std::uint32_t(v.trace.info.x) > info.maxImageDimension2D || std::uint32_t(v.trace.info.y) > info.maxImageDimension2D)
      throwBadInput(lightPath(scene, v) + ": " + std::to_string(v.trace.info.x) + " texels exceed maxImageDimension2D (" +
                    std::to_string(info.maxImageDimension2D) + ") of " + info.name + " (or use --backend cpu)");
    if (bytes > info.maxMemoryAllocationSize || 2 * bytes > info.deviceLocalBytes)
      throwBadInput(lightPath(scene, v) + ": one " + std::to_string(v.trace.info.x) + "x" +
                    std::to_string(v.trace.info.y) + " layer needs " + formatBytes(bytes) + " on the device and as much to read it back; " +
                    info.name + " has " + formatBytes(info.deviceLocalBytes) + " (largest allocation " +
                    formatBytes(info.maxMemoryAllocationSize) + "); lower the resolution or use --backend cpu");
  }
}


// Views of one size are traced together, in batches of viewsPerBatch (one submission and one readback
// each); views of different sizes go in separate calls, so the image array is never padded to the largest.
std::vector<ShadowLayer> traceInBatches(const Scene& scene, const std::vector<LightView>& views, Tracer& tracer,
                                        VulkanBakeStats& stats) {
  const VulkanTracer& vulkan = *tracer.vulkan();
  stats.device = tracer.deviceName();
  stats.pipeline = vulkan.pipelineStats();
  if (!stats.pipeline.cacheError.empty())
    std::fprintf(stderr, "voxshadow: warning: pipeline cache: %s\n", stats.pipeline.cacheError.c_str());
  tracer.setScene(scene.data());
  stats.boxTable = vulkan.boxTableInUse();
  std::vector<std::pair<int, int>> sizes;
  for (const LightView& v : views) {
    std::pair<int, int> size(v.trace.info.x, v.trace.info.y);
    if (std::find(sizes.begin(), sizes.end(), size) == sizes.end()) sizes.push_back(size);
  }
  Progress progress("tracing (" + tracer.deviceName() + ")");
  std::vector<ShadowLayer> layers(views.size());
  stats.viewGpuMs.assign(views.size(), -1.0);
  std::size_t done = 0;
  for (const auto& size : sizes) {
    std::vector<std::size_t> members;
    for (std::size_t i = 0; i < views.size(); ++i)
      if (views[i].trace.info.x == size.first && views[i].trace.info.y == size.second) members.push_back(i);
    const std::size_t batch = viewsPerBatch(vulkan.device(), views[members[0]]);
    for (std::size_t first = 0; first < members.size(); first += batch) {
      const std::size_t count = std::min(batch, members.size() - first);
      std::vector<gpu::TraceView> group;
      for (std::size_t k = 0; k < count; ++k) group.push_back(views[members[first + k]].trace);
      std::vector<ShadowLayer> out;
      TraceStats t = tracer.traceShadow(group, out);
      ++stats.dispatchCalls;
      stats.wallMs += t.wallMs;
      for (std::size_t k = 0; k < count; ++k) {
        layers[members[first + k]] = std::move(out[k]);
        if (k < t.viewGpuMs.size()) stats.viewGpuMs[members[first + k]] = t.viewGpuMs[k];
      }
      done += count;
      progress.update(done, views.size());
    }
  }
  progress.finish();
  return layers;
}

// What the bake holds in host memory at its peak: every layer (they are written together), one more layer's
// worth for the EXR writer, the preview sheet, and on a CPU Vulkan device (lavapipe, whose device memory
// is host memory) a batch's image and readback and the driver's own working memory.
// What addEvsmMoments holds besides the baked layers: two copies of every layer (its own and the moment
// pass's inputs), and per EVSM layer its moments, their scratch and the copy the EXR writer interleaves
// (16 bytes a texel each).
std::uint64_t evsmMomentBytes(const SceneDesc& desc, const std::vector<LightView>& views) {
  std::uint64_t need = 0;
  for (const LightView& v : views) {
    need += 2 * layerBytes(v);
    const LightDesc& l = desc.lights[std::size_t(v.lightIndex)];
    if (l.shadow && l.shadow->filter == ShadowFilter::Evsm) need += layerBytes(v) / sizeof(float) * 48;
  }
  return need;
}

std::uint64_t hostBytesNeeded(const std::vector<LightView>& views, bool preview, const VulkanDeviceInfo* device) {
  std::uint64_t total = 0, largest = 0, batch = 0;
  for (const LightView& v : views) {
    total += layerBytes(v);
    largest = std::max(largest, layerBytes(v));
    if (!device) continue;
    // A batch holds views of one size, as many as there are up to viewsPerBatch.
    const std::size_t sameSize = std::size_t(std::count_if(views.begin(), views.end(), [&](const LightView& w) {
      return w.trace.info.x == v.trace.info.x && w.trace.info.y == v.trace.info.y;
    }));
    batch = std::max(batch, layerBytes(v) * std::min(sameSize, viewsPerBatch(*device, v)));
  }
  total += largest;
  if (preview) total += 4096ull * 4096ull * 3ull;
  if (device && device->type == VulkanDeviceType::Cpu) total += 2 * batch + kCpuVulkanDeviceWorkingBytes;
  return total;
}

void checkHostMemory(const Scene& scene, const std::vector<LightView>& views, const BakeOptions& options,
                     const VulkanDeviceInfo* device) {
  std::uint64_t need = hostBytesNeeded(views, options.preview.has_value(), device);
  if (options.evsmMoments) need += evsmMomentBytes(scene.desc(), views);
  std::uint64_t texels = 0;
  for (const LightView& v : views) texels += layerBytes(v) / sizeof(float);
  checkMemoryNeed(need, memoryBudget(options.memoryBudget, tracingCommandThreads(options.threads)),
                  scene.desc().file.string() + ": lights: " + std::to_string(views.size()) + " shadow layers (" +
                      std::to_string(texels) + " texels) need",
                  "lower the lights' shadow.resolution or shadow fewer lights");
}

BakedView toBaked(const LightView& v, ShadowLayer&& layer) {
  BakedView b;
  b.light = v.light;
  b.name = v.name;
  b.encoding = v.encoding == gpu::VS_ENCODING_LINEAR_DISTANCE ? "linear_distance" : "ndc_depth";
  b.depthPoint = v.depthPoint == gpu::VS_DEPTH_POINT_VOXEL_CENTER ? "voxel_center" : "entry";
  b.range = v.range;
  if (v.encoding == gpu::VS_ENCODING_LINEAR_DISTANCE) b.position = v.position;
  b.worldToClip = v.viewProj;
  b.eye = v.eye;
  b.eyeToClip = v.eyeToClip;
  b.width = layer.width;
  b.height = layer.height;
  b.texels = std::move(layer.texels);
  return b;
}

// The views' metadata as the EXR and its sidecar carry it (texels left empty).
std::vector<BakedView> viewRecords(const std::vector<LightView>& views) {
  std::vector<BakedView> records;
  for (const LightView& v : views) {
    ShadowLayer empty;
    empty.width = v.trace.info.x;
    empty.height = v.trace.info.y;
    records.push_back(toBaked(v, std::move(empty)));
  }
  return records;
}

// The live instances' world boxes: what the shard plan weighs tiles by.
std::vector<Aabb> casterBoxes(const Scene& scene) {
  const SceneData& data = scene.data();
  std::vector<Aabb> boxes;
  for (std::size_t i = 0; i < data.instanceBounds.size(); ++i)
    if (i >= data.instanceSlots.size() || data.instanceSlots[i]) boxes.push_back(data.instanceBounds[i]);
  return boxes;
}

// Traces the tiles of shard `k` and returns their texels in the part's order. Each run of tiles along one row
// of one layer is one trace call (its rectangle): a texel's ray depends on its view and coordinates alone, so
// the texels are those of a whole-layer bake, bit for bit.
std::vector<float> traceShard(const Scene& scene, const std::vector<LightView>& views, const ShardPlan& plan, int k,
                              Tracer& tracer) {
  std::span<const ShardTile> tiles = plan.shardTiles(k);
  std::uint64_t total = 0, done = 0;
  for (const ShardTile& t : tiles) total += t.texels();
  std::vector<float> texels;
  texels.reserve(total);
  Progress progress("tracing shard " + std::to_string(k) + " of " + std::to_string(plan.shards) +
                    (tracer.vulkan() ? " (" + tracer.deviceName() + ")" : ""));
  tracer.setScene(scene.data());
  std::vector<ShadowLayer> layer(1);
  int layerView = -1;
  for (std::size_t i = 0; i < tiles.size();) {
    std::size_t end = i + 1;
    while (end < tiles.size() && tiles[end].view == tiles[i].view && tiles[end].y0 == tiles[i].y0) ++end;
    if (tiles[i].view != layerView) {
      layer[0] = ShadowLayer{};
      layerView = tiles[i].view;
    }
    gpu::TraceView run = views[std::size_t(layerView)].trace;
    run.rect = glm::ivec4(tiles[i].x0, tiles[i].y0, tiles[end - 1].x1, tiles[i].y1);
    tracer.traceShadow(std::span<const gpu::TraceView>(&run, 1), layer);
    for (std::size_t t = i; t < end; ++t) {
      for (int y = tiles[t].y0; y < tiles[t].y1; ++y) {
        const float* row = &layer[0].texels[std::size_t(y) * std::size_t(layer[0].width) + std::size_t(tiles[t].x0)];
        texels.insert(texels.end(), row, row + (tiles[t].x1 - tiles[t].x0));
      }
      done += tiles[t].texels();
    }
    progress.update(done, total);
    i = end;
  }
  progress.finish();
  return texels;
}

// Host memory of a shard: the largest layer it touches (traced whole-layer sized) and its own texels.
void checkShardMemory(const Scene& scene, const std::vector<LightView>& views, const ShardPlan& plan, int k,
                      const BakeOptions& options) {
  std::uint64_t texels = 0, largest = 0;
  for (const ShardTile& t : plan.shardTiles(k)) {
    texels += t.texels();
    largest = std::max(largest, layerBytes(views[std::size_t(t.view)]));
  }
  checkMemoryNeed(texels * sizeof(float) + largest, memoryBudget(options.memoryBudget, tracingCommandThreads(options.threads)),
                  scene.desc().file.string() + ": shard " + std::to_string(k) + " of " + std::to_string(plan.shards) +
                      " (" + std::to_string(texels) + " texels)",
                  "bake in more shards or lower the lights' shadow.resolution");
}

std::string hostName() {
  char name[256] = {};
  if (gethostname(name, sizeof(name) - 1) != 0) return "";
  return name;
}

// The shards of one bake, traced on this machine one after another into part files. The scene, its views,
// the plan and the tracer are made once, on the first shard that needs them.
class ShardBaker {
 public:
  ShardBaker(const BakeOptions& options, const SceneDesc& desc, const BakeInputs& inputs, int shards)
      : options_(options), desc_(desc), inputs_(inputs), shards_(shards) {}

  // The scene's shadow views (the scene is loaded on first use, once).
  const std::vector<LightView>& views() {
    if (!scene_) {
      scene_.emplace(Scene::load(SceneDesc(desc_)));
      views_ = scene_->lightViews();
      if (views_.empty()) throwBadInput(desc_.file.string() + ": lights: no light casts a shadow, nothing to bake");
      plan_ = planShards(views_, casterBoxes(*scene_), shards_);
    }
    return views_;
  }

  void bake(int k, const std::filesystem::path& part) {
    views();
    checkShardMemory(*scene_, views_, plan_, k, options_);
    if (!tracer_) {
      if (options_.backend == "cpu") {
        tracer_ = makeCpuTracer({CpuTracePath::Interleaved, options_.threads});
      } else {
        tracer_ = openVulkanBackend(options_.device, options_.threads);
      }
    }
    if (tracer_->vulkan()) {
      std::vector<LightView> touched;
      for (const ShardTile& t : plan_.shardTiles(k))
        if (touched.empty() || touched.back().name != views_[std::size_t(t.view)].name)
          touched.push_back(views_[std::size_t(t.view)]);
      checkDeviceFits(*scene_, touched, tracer_->vulkan()->device());
    }
    auto t0 = Clock::now();
    std::vector<float> texels = traceShard(*scene_, views_, plan_, k, *tracer_);
    nlohmann::json assets = nlohmann::json::array();
    for (const BakeInputs::Asset& a : inputs_.assets) assets.push_back(a.file.string());
    const nlohmann::json producer = {{"scene", desc_.file.string()},
                                     {"assets", std::move(assets)},
                                     {"backend", tracer_->vulkan() ? "vulkan: " + tracer_->deviceName() : "cpu"},
                                     {"host", hostName()}};
    writeBakePart(part, partManifest(inputs_, plan_, k, viewRecords(views_), producer), texels);
    std::printf("baked shard %d of %d (%zu tiles, %zu texels, %.2f s) into %s\n", k, shards_,
                plan_.shardTiles(k).size(), texels.size(), secondsSince(t0), part.c_str());
    std::fflush(stdout);
  }

 private:
  const BakeOptions& options_;
  const SceneDesc& desc_;
  const BakeInputs& inputs_;
  int shards_;
  std::optional<Scene> scene_;
  std::vector<LightView> views_;
  ShardPlan plan_;
  std::unique_ptr<Tracer> tracer_;
};

// EVSM: each EVSM light's moment layers (lighting/evsm.h) into `baked` (window order, as the texels), made
// with the CPU moment pass from the baked depths. Preconditions: baked[i] from views[i], whole.
void addEvsmMoments(const SceneDesc& desc, std::vector<LightView> views, std::vector<BakedView>& baked) {
  // The bake's layers are in window order: rings at offset 0 store them so.
  for (LightView& v : views) v.windowOrigin = glm::i64vec2(0);
  std::vector<ShadowLayer> layers(views.size());
  for (std::size_t i = 0; i < views.size(); ++i) {
    layers[i].width = baked[i].width;
    layers[i].height = baked[i].height;
    layers[i].texels = baked[i].texels;
  }
  const ShadeInputs inputs = makeShadeInputs(desc, views, layers, false);
  for (std::size_t i = 0; i < views.size(); ++i) {
    if (!hasMoments(inputs, i)) continue;
    const std::size_t n = baked[i].texels.size();
    const auto first = inputs.moments.begin() + inputs.views[i].trace.w;
    baked[i].moments.assign(first, first + std::ptrdiff_t(n));
    const ShadowDesc& s = *desc.lights[std::size_t(views[i].lightIndex)].shadow;
    baked[i].evsmExponents = glm::vec2(s.evsmPositiveExponent, s.evsmNegativeExponent);
    baked[i].evsmBlur = s.evsmBlur;
    baked[i].lightBleedReduction = s.lightBleedReduction;
  }
}

// --evsm-moments needs an EVSM light, whose moments a bake of whole layers makes.
void checkEvsmMoments(const BakeOptions& options, const SceneDesc& desc) {
  if (!options.evsmMoments) return;
  const bool any = std::any_of(desc.lights.begin(), desc.lights.end(), [](const LightDesc& l) {
    return l.enabled && l.shadow && l.shadow->filter == ShadowFilter::Evsm;
  });
  if (!any)
    throwBadInput(options.scene.string() + ": lights: --evsm-moments writes the moments of EVSM lights, and no light's "
                  "shadow.filter is \"evsm\"");
}

void checkShardOptions(const BakeOptions& options) {
  if (options.shard && options.evsmMoments)
    throwBadInput("--evsm-moments: a shard holds part of a layer, and moments blur across whole layers; give "
                  "--evsm-moments to bake --shards N --parts DIR, which merges the parts");
  if (options.shard && (options.shards || options.partsDir || options.missingShards))
    throwBadInput("--shard bakes one part file; it cannot be combined with --shards, --parts or --missing-shards");
  if (options.shard) {
    if (options.output.empty()) throwBadInput("--shard needs -o PART.vspart, the part file to write");
    if (!hasExtension(options.output, ".vspart"))
      throwBadInput(options.output.string() + ": a shard's output must be a .vspart part file");
    if (options.preview) throwBadInput("--preview: a shard writes no preview (merge the parts with --preview)");
    return;
  }
  if (options.shards && !options.partsDir) throwBadInput("--shards needs --parts DIR, where the part files go");
  if (options.partsDir && !options.shards) throwBadInput("--parts needs --shards N");
  if (options.missingShards && !options.shards) throwBadInput("--missing-shards needs --shards N and --parts DIR");
  if (options.partsDir) {
    std::error_code ec;
    if (fs::exists(*options.partsDir, ec) && !fs::is_directory(*options.partsDir, ec))
      throwBadInput(options.partsDir->string() + ": --parts must be a directory");
  }
}

// bake --shard K/N -o PART: one shard, or nothing when PART already holds it for the same inputs.
void runBakeShard(const BakeOptions& options) {
  const auto [k, n] = *options.shard;
  checkInputBytes(options.scene, InputKind::Scene);
  SceneDesc desc = parseSceneFile(options.scene);
  checkSceneAssetBytes(desc);
  checkCommandOutputs(desc, {options.output});
  const BakeInputs inputs = hashBakeInputs(desc);
  std::string why;
  if (partUpToDate(options.output, inputs, k, n, &why)) {
    std::printf("up to date: %s\n", options.output.c_str());
    return;
  }
  ShardBaker(options, desc, inputs, n).bake(k, options.output);
}

// bake --shards N --parts DIR [-o OUT.exr | --missing-shards]: the shards whose parts are missing or stale,
// then the merge; or only the list of those shards.
void runShardedBake(const BakeOptions& options) {
  const int n = *options.shards;
  if (n < 1 || n > kMaxShards)
    throwBadInput("--shards: must be between 1 and " + std::to_string(kMaxShards) + ", not " + std::to_string(n));
  checkInputBytes(options.scene, InputKind::Scene);
  SceneDesc desc = parseSceneFile(options.scene);
  checkSceneAssetBytes(desc);
  checkEvsmMoments(options, desc);
  const BakeInputs inputs = hashBakeInputs(desc);
  const fs::path dir = *options.partsDir;
  std::vector<fs::path> parts;
  std::vector<int> stale;
  for (int k = 0; k < n; ++k) {
    parts.push_back(dir / partFileName(k, n));
    if (!partUpToDate(parts.back(), inputs, k, n)) stale.push_back(k);
  }
  if (options.missingShards) {
    for (std::size_t i = 0; i < stale.size(); ++i) std::printf("%s%d", i ? "," : "", stale[i]);
    std::printf("\n");
    return;
  }
  if (options.output.empty()) throwBadInput("-o,--output is required (or --missing-shards)");
  const std::vector<fs::path> outputs = bakeOutputPaths(options.output, options.preview);
  checkCommandOutputs(desc, outputs, kMaxShadowFileNameBytes);
  refuseOutputsOverInputs(outputs, parts, std::vector<std::string>(parts.size(), "part"));
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throwBadInput(dir.string() + ": cannot create the parts directory: " + ec.message());
  checkCommandOutputs(desc, parts);
  std::printf("%zu of %d shard%s to bake, %zu up to date in %s\n", stale.size(), n, n == 1 ? "" : "s",
              std::size_t(n) - stale.size(), dir.c_str());
  std::fflush(stdout);
  ShardBaker baker(options, desc, inputs, n);
  for (int k : stale) baker.bake(k, parts[std::size_t(k)]);
  std::vector<BakedView> views = mergeBakeParts(parts);
  if (options.evsmMoments) {
    const std::vector<LightView>& lightViews = baker.views();
    std::uint64_t merged = 0;
    for (const BakedView& v : views) merged += v.texels.size() * sizeof(float);
    checkMemoryNeed(merged + evsmMomentBytes(desc, lightViews),
                    memoryBudget(options.memoryBudget, tracingCommandThreads(options.threads)),
                    options.scene.string() + ": --evsm-moments: the merged layers and their moments need",
                    "lower the EVSM lights' shadow.resolution, or bake without --evsm-moments");
    addEvsmMoments(desc, lightViews, views);
  }
  writeBakeOutputs(options.output, options.preview, views);
  std::printf("merged %d part%s into %s\n", n, n == 1 ? "" : "s", options.output.c_str());
  if (options.preview) std::printf("preview: %s\n", options.preview->c_str());
}

}  // namespace

std::vector<fs::path> bakeOutputPaths(const fs::path& exr, const std::optional<fs::path>& preview) {
  if (!hasExtension(exr, ".exr")) throwBadInput(exr.string() + ": the output must be an .exr file");
  if (preview && !hasExtension(*preview, ".png")) throwBadInput(preview->string() + ": the preview must be a .png file");
  std::vector<fs::path> outputs = {exr, sidecarPath(exr)};
  if (preview) outputs.push_back(*preview);
  return outputs;
}

void checkCommandOutputs(const SceneDesc& scene, const std::vector<std::filesystem::path>& outputs,
                         std::size_t maxFirstNameBytes) {
  std::vector<std::filesystem::path> inputs = {scene.file};
  std::vector<std::string> inputWhat = {"scene"};
  for (const AssetDesc& a : scene.assets) {
    inputs.push_back(a.file);
    inputWhat.push_back("asset '" + a.name + "'");
  }
  refuseOutputsOverInputs(outputs, inputs, inputWhat);
  for (std::size_t i = 0; i < outputs.size(); ++i) checkOutputDirectory(outputs[i], i == 0 ? maxFirstNameBytes : 255);
}

namespace {

VulkanOptions vulkanOptions(const std::string& device, int hostThreads) {
  VulkanOptions o;
  o.hostThreads = hostThreads;
  if (device.empty()) return o;
  if (device.find_first_not_of("0123456789") == std::string::npos && device.size() < 9) o.deviceIndex = std::stoi(device);
  else o.deviceName = device;
  return o;
}

}  // namespace

std::unique_ptr<Tracer> openVulkanBackend(const std::string& device, int hostThreads) {
  try {
    return makeVulkanTracer(vulkanOptions(device, hostThreads));
  } catch (const Error& e) {
    if (e.kind() != ErrorKind::Runtime) throw;
    throwRuntime(std::string(e.what()) + " (to trace without Vulkan, use --backend cpu)");
  }
}

void runBake(const BakeOptions& options) {
  // Every check of the user's paths comes before the scene is loaded or traced.
  if (options.backend != "cpu" && options.backend != "vulkan")
    throwBadInput("unknown backend '" + options.backend + "' (cpu or vulkan)");
  if (!options.device.empty() && options.backend != "vulkan")
    throwBadInput("--device chooses a Vulkan device; it needs --backend vulkan");
  if (options.threads < 0 || options.threads > kMaxThreads)
    throwBadInput("--threads: must be between 0 and " + std::to_string(kMaxThreads) + ", not " + std::to_string(options.threads));
  checkShardOptions(options);
  if (options.shard) return runBakeShard(options);
  if (options.shards) return runShardedBake(options);
  if (options.output.empty()) throwBadInput("-o,--output is required");
  const std::vector<fs::path> outputs = bakeOutputPaths(options.output, options.preview);

  auto t0 = Clock::now();
  checkInputBytes(options.scene, InputKind::Scene);
  SceneDesc desc = parseSceneFile(options.scene);
  checkSceneAssetBytes(desc);
  checkCommandOutputs(desc, outputs, kMaxShadowFileNameBytes);
  checkEvsmMoments(options, desc);

  Scene scene = Scene::load(std::move(desc));
  double loadSeconds = secondsSince(t0);
  std::vector<LightView> views = scene.lightViews();
  if (views.empty()) throwBadInput(options.scene.string() + ": lights: no light casts a shadow, nothing to bake");

  auto t1 = Clock::now();
  VulkanBakeStats vulkanStats;
  std::vector<ShadowLayer> layers;
  if (options.backend == "cpu") {
    checkHostMemory(scene, views, options, nullptr);
    std::unique_ptr<Tracer> tracer = makeCpuTracer({CpuTracePath::Interleaved, options.threads});
    layers = traceInBands(scene, views, *tracer);
  } else {
    // The layers alone first: a bake that cannot fit them is refused before the Vulkan driver maps its own share
    // of the address space (under a tight ulimit -v, lavapipe can crash creating its pipeline).
    checkHostMemory(scene, views, options, nullptr);
    std::unique_ptr<Tracer> tracer = openVulkanBackend(options.device, options.threads);
    const VulkanDeviceInfo& device = tracer->vulkan()->device();
    checkDeviceFits(scene, views, device);
    checkHostMemory(scene, views, options, &device);
    layers = traceInBatches(scene, views, *tracer, vulkanStats);
  }
  double traceSeconds = secondsSince(t1);

  std::vector<BakedView> baked;
  baked.reserve(views.size());
  std::uint64_t texels = 0;
  for (std::size_t i = 0; i < views.size(); ++i) {
    texels += layers[i].texels.size();
    baked.push_back(toBaked(views[i], std::move(layers[i])));
  }
  if (options.evsmMoments) addEvsmMoments(scene.desc(), views, baked);
  auto t2 = Clock::now();
  // One bake, one outcome: the EXR, its sidecar and the preview are committed together or not at all.
  writeBakeOutputs(options.output, options.preview, baked);
  double writeSeconds = secondsSince(t2);

  std::printf("baked %zu view%s into %s\n", baked.size(), baked.size() == 1 ? "" : "s", options.output.c_str());
  for (const BakedView& b : baked)
    std::printf("  %-24s %5dx%-5d %s, %s%s\n", b.name.c_str(), b.width, b.height, b.encoding.c_str(),
                b.depthPoint.c_str(), b.moments.empty() ? "" : ", EVSM moments");
  if (options.preview) std::printf("preview: %s\n", options.preview->c_str());
  if (options.stats) {
    std::printf("stats: backend %s, threads %d\n", options.backend.c_str(), options.threads);
    std::printf("  load  %.3f s (%zu objects, %zu instances)\n", loadSeconds, scene.objects().size(),
                scene.instances().size());
    std::printf("  trace %.3f s, %llu rays, %.2f Mrays/s\n", traceSeconds, static_cast<unsigned long long>(texels),
                traceSeconds > 0.0 ? double(texels) / traceSeconds * 1e-6 : 0.0);
    if (options.backend == "vulkan") {
      const PipelineStats& p = vulkanStats.pipeline;
      std::error_code ec;
      auto cacheBytes = std::filesystem::file_size(p.cacheFile, ec);
      std::printf("  device %s, %zu trace call%s (one per view size), walk through the %s\n",
                  vulkanStats.device.c_str(), vulkanStats.dispatchCalls, vulkanStats.dispatchCalls == 1 ? "" : "s",
                  vulkanStats.boxTable ? "box table" : "brickmap hierarchy");
      // A cache file the driver keeps nothing in (lavapipe's holds a header only) saves no work: not "warm".
      const char* cacheState = p.warmCache ? "warm" : p.cacheEmpty ? "empty (the driver caches nothing)" : "cold";
      std::printf("  pipeline creation %.1f ms, %s cache (%s, %llu bytes%s)\n", p.createMs, cacheState,
                  p.cacheFile.c_str(), ec ? 0ull : (unsigned long long)cacheBytes,
                  p.cacheSaved ? "" : (", not saved: " + p.cacheError).c_str());
      for (std::size_t i = 0; i < baked.size(); ++i) {
        double rays = double(baked[i].width) * double(baked[i].height);
        double ms = vulkanStats.viewGpuMs[i];
        if (ms > 0.0)
          std::printf("  view %-24s %10.0f rays  %9.2f ms GPU  %8.2f Mrays/s\n", baked[i].name.c_str(), rays, ms,
                      rays / (ms * 1e3));
        else
          std::printf("  view %-24s %10.0f rays  (no GPU timestamps)\n", baked[i].name.c_str(), rays);
      }
    }
    std::printf("  write %.3f s\n", writeSeconds);
  }
}

void registerBake(CLI::App& app) {
  auto options = std::make_shared<BakeOptions>();
  CLI::App* sub = app.add_subcommand("bake", "Trace a scene's shadow maps into a multi-layer EXR (+ JSON sidecar)");
  sub->add_option("SCENE", options->scene, "Scene file (JSON, version 1)")->required();
  sub->add_option("-o,--output", options->output,
                  "Output .exr (its directory must exist); with --shard, the shard's .vspart part file");
  sub->add_option("--backend", options->backend, "Trace backend")
      ->check(CLI::IsMember({"cpu", "vulkan"}))
      ->capture_default_str();
  sub->add_option("--preview", options->preview, "Also write a PNG contact sheet of the layers");
  addThreadsOption(sub, options->threads, "CPU threads: the CPU backend's tracing and either backend's host work (0: all)", 0);
  sub->add_option_function<std::string>(
         "--memory-budget",
         [options](const std::string& text) { options->memoryBudget = parseByteSize(text, "--memory-budget"); },
         "Most host memory the bake may plan to use, e.g. 8G, 512M (default: the memory available now)")
      ->type_name("SIZE");
  sub->add_option("--device", options->device,
                  "Vulkan device: an index or part of a name from `voxshadow info --devices` (default: best)");
  sub->add_flag("--stats", options->stats,
                "Print timings and ray throughput (Vulkan: per-view GPU time and the pipeline creation time)");
  sub->add_option_function<std::string>(
         "--shard", [options](const std::string& text) { options->shard = parseShard(text); },
         "Bake only shard K of N (0 <= K < N) into the part file -o PART.vspart; nothing when it is up to date")
      ->type_name("K/N");
  sub->add_option("--shards", options->shards, "With --parts: bake in N shards on this machine, then merge")
      ->type_name("N");
  sub->add_option("--parts", options->partsDir,
                  "With --shards: the directory of the part files (kept: a rerun bakes only missing or stale parts)")
      ->type_name("DIR");
  sub->add_flag("--evsm-moments", options->evsmMoments,
                "Also write the EVSM lights' moment layers as channels evsm.p, evsm.p2, evsm.n, evsm.n2");
  sub->add_flag("--missing-shards", options->missingShards,
                "With --shards and --parts: print the shards whose parts are missing or stale (K,K,...) and stop");
  sub->callback([options] { runBake(*options); });
}

std::pair<int, int> parseShard(const std::string& text) {
  auto bad = [&] {
    throwBadInput("--shard: expected K/N with 0 <= K < N <= " + std::to_string(kMaxShards) + ", not '" + text + "'");
  };
  const std::size_t slash = text.find('/');
  if (slash == std::string::npos || slash == 0 || slash + 1 == text.size() || slash > 4 || text.size() - slash - 1 > 4) bad();
  const std::string a = text.substr(0, slash), b = text.substr(slash + 1);
  if (a.find_first_not_of("0123456789") != std::string::npos || b.find_first_not_of("0123456789") != std::string::npos) bad();
  const int k = std::stoi(a), n = std::stoi(b);
  if (n < 1 || n > kMaxShards || k >= n) bad();
  return {k, n};
}

}  // namespace vs::cli
