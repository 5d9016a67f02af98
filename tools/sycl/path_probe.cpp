// Finds megakernel launches that do not end on a SYCL device, and records such a path bounce by bounce.
//
// A diagnosis tool for device code generation (built with -DPT_SYCL=ON under AdaptiveCpp as pt_sycl_path_probe):
//   pt_sycl_path_probe find SCENE WIDTH HEIGHT FIRST LAST [SECONDS]
//     launches the megakernel for samples FIRST..LAST (MegakernelSample, one sample per launch, as GPUs run it); every work item marks
//     in host memory that it started and that it finished, so when a launch has not ended after SECONDS (default 5)
//     the pixels that started and never finished are printed (as "stuck X Y SAMPLE"), and the program exits 3.
//   pt_sycl_path_probe trace SCENE WIDTH HEIGHT X Y SAMPLE [SECONDS]
//     traces that one sample on the host and then on the device, each bounce's ray and hit recorded as it happens
//     (the device writes host memory, so a path that never ends still shows how far it came); the device's BVH walk
//     is a counted copy of closest_hit_binary that gives up after a bound on node visits and says so. Exits 4 when
//     the two paths differ in their steps, bounces or primitives hit.
//   pt_sycl_path_probe region SCENE WIDTH HEIGHT X0 Y0 W H SAMPLE KIND SECONDS
//     one launch of that sample over a rectangle of the image (see region() for the kinds).
// The device is the first GPU AdaptiveCpp lists (the default device where there is none). Exit status 0: everything ended.
#include <sycl/sycl.hpp>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

#include "flat/flat_scene.hpp"
#include "loading/scene_loader.hpp"
#include "scene/scene.hpp"

namespace {

using namespace pt;
using T = float;
using Clock = std::chrono::steady_clock;

constexpr u32 kMaxRecords = 256;
constexpr u32 kVisitLimit = 1u << 20;  // node visits of one walk before the counted walk gives up

// One step of a traced path, as the device wrote it.
struct Record {
  u32 bounce;
  u32 stage;  // 1: about to walk the BVH with `ray`; 2: hit; 3: escaped; 4: scattered; 5: absorbed; 6: walk gave up
  float origin[3], direction[3];
  float t;
  u32 primitive;
  u32 visits;  // node visits of the walk
};

struct Trace {
  u32 records;
  Record record[kMaxRecords];
};

template <class V>
void print_vec(const char* name, const V& v) {
  std::printf(" %s (%.9g %.9g %.9g)", name, static_cast<double>(v.x), static_cast<double>(v.y), static_cast<double>(v.z));
}

// The walk of closest_hit_binary with a count of its node visits, given up at kVisitLimit.
struct VisitCounter {
  u32& visits;
  template <class T>
  PT_HD void box_test(const BvhNode<T>&, const BoxRay<T>&, T, T) const {}
  PT_HD bool keep_walking() const { return ++visits < kVisitLimit; }
};

template <class T>
PT_HD bool counted_walk(const SceneView<T>& scene, const Ray<T>& ray, const IntersectContext<T>& context, Hit<T>& hit, u32& visits) {
  visits = 0;
  return closest_hit_binary(scene, ray, context, hit, largest<T>(), VisitCounter{visits});
}

// The megakernel's trace_sample, writing each step into `trace` (host memory on the device) before going on.
template <class T>
PT_HD void traced_sample(const SceneView<T>& scene, u32 x, u32 y, u32 sample, Trace* trace) {
  const SampleRandom random = path_random(scene.params, y * scene.params.width + x, sample);
  PathState<T> path = start_path(scene, x, y, random);
  u32 n = 0;
  auto write = [&](u32 stage, const Hit<T>& hit, u32 visits) {
    if (n >= kMaxRecords) return;
    Record& r = trace->record[n++];
    r.bounce = path.bounce;
    r.stage = stage;
    r.origin[0] = path.ray.origin.x, r.origin[1] = path.ray.origin.y, r.origin[2] = path.ray.origin.z;
    r.direction[0] = path.ray.direction.x, r.direction[1] = path.ray.direction.y, r.direction[2] = path.ray.direction.z;
    r.t = hit.t;
    r.primitive = hit.primitive;
    r.visits = visits;
    sycl::atomic_ref<u32, sycl::memory_order::relaxed, sycl::memory_scope::system> count(trace->records);
    count.store(n, sycl::memory_order::release);  // the record before the count that shows it
  };
  while (path.bounce < scene.params.max_depth && n < kMaxRecords) {
    Hit<T> hit{};
    write(1, hit, 0);
    u32 visits = 0;
    const bool found = counted_walk(scene, path.ray, IntersectContext<T>{scene.boundaries, &random, path.bounce}, hit, visits);
    if (visits >= kVisitLimit) {
      write(6, hit, visits);
      return;
    }
    if (!found) {
      write(3, hit, visits);
      path_escaped(scene, path);
      break;
    }
    write(2, hit, visits);
    ShadowRay<T> shadow;  // the probe follows the path's own rays; shadow rays are left untraced
    if (!path_shade(scene, path, hit, random, shadow)) {
      write(5, hit, visits);
      break;
    }
    write(4, hit, visits);
  }
}

void print_trace(const char* where, const Trace& trace) {
  std::printf("%s: %u records\n", where, trace.records);
  const char* stages[] = {"?", "walk", "hit", "escaped", "scattered", "absorbed", "WALK GAVE UP"};
  for (u32 i = 0; i < trace.records && i < kMaxRecords; ++i) {
    const Record& r = trace.record[i];
    std::printf("  bounce %2u %-12s o (%.9g %.9g %.9g) d (%.9g %.9g %.9g) t %.9g prim %u visits %u\n", r.bounce, stages[r.stage < 7 ? r.stage : 0],
                r.origin[0], r.origin[1], r.origin[2], r.direction[0], r.direction[1], r.direction[2], static_cast<double>(r.t), r.primitive,
                r.visits);
  }
  std::fflush(stdout);
}

sycl::queue gpu_queue() {
  for (const sycl::device& d : sycl::device::get_devices())
    if (d.is_gpu()) return sycl::queue(d, sycl::property::queue::in_order());
  std::printf("no SYCL GPU: the default device instead\n");
  return sycl::queue(sycl::default_selector_v, sycl::property::queue::in_order());
}

template <class E>
const E* upload(sycl::queue& queue, const std::vector<E>& array) {
  E* p = sycl::malloc_device<E>(std::max<std::size_t>(array.size(), 1), queue);
  if (!array.empty()) queue.memcpy(p, array.data(), array.size() * sizeof(E)).wait();
  return p;
}

// Waits in another thread (a wait is what submits the runtime's queued work), so that the caller can give up.
bool wait_for(sycl::event event, double seconds) {
  auto* done = new std::atomic<bool>(false);  // left to the waiting thread when the launch never ends
  std::thread([event, done]() mutable {
    event.wait();
    done->store(true);
  }).detach();
  const Clock::time_point start = Clock::now();
  while (!done->load()) {
    if (std::chrono::duration<double>(Clock::now() - start).count() > seconds) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return true;
}

int find(sycl::queue& queue, const SceneView<T>& view, u32 first, u32 last, double seconds) {
  const u32 width = view.params.width, height = view.params.height;
  const std::size_t pixels = static_cast<std::size_t>(width) * height;
  FilmPixel* film = sycl::malloc_device<FilmPixel>(pixels, queue);
  queue.memset(film, 0, pixels * sizeof(FilmPixel)).wait();
  u32* state = sycl::malloc_host<u32>(pixels, queue);
  for (u32 s = first; s <= last; ++s) {
    std::fill(state, state + pixels, 0u);
    const MegakernelSample<T> pass{view, film, s};
    const sycl::range<2> group(8, 16);
    const sycl::range<2> global((height + 7) / 8 * 8, (width + 15) / 16 * 16);
    const sycl::event event = queue.parallel_for(sycl::nd_range<2>(global, group), [=](sycl::nd_item<2> item) {
      const u32 x = static_cast<u32>(item.get_global_id(1)), y = static_cast<u32>(item.get_global_id(0));
      if (x >= width || y >= height) return;
      sycl::atomic_ref<u32, sycl::memory_order::relaxed, sycl::memory_scope::system> mark(state[static_cast<std::size_t>(y) * width + x]);
      mark.store(1u);
      pass(x, y);
      mark.store(2u);
    });
    if (wait_for(event, seconds)) {
      std::printf("sample %u ended\n", s);
      std::fflush(stdout);
      continue;
    }
    std::size_t started = 0, unstarted = 0;
    for (std::size_t p = 0; p < pixels; ++p) {
      const u32 v = __atomic_load_n(&state[p], __ATOMIC_RELAXED);
      if (v == 1 && started++ < 64) std::printf("stuck %zu %zu %u\n", p % width, p / width, s);
      if (v == 0) ++unstarted;
    }
    std::printf("sample %u has not ended after %.1f s: %zu work items started and unfinished, %zu not started\n", s, seconds, started, unstarted);
    std::fflush(stdout);
    std::_Exit(3);
  }
  return 0;
}

// One launch of sample `sample` over the rectangle (x0, y0, w, h) of the image in groups of 16x8 as the backend's
// (kind "mega": the megakernel as GPUs run it, MegakernelSample; "mega-loop": MegakernelPass with a count of one,
// the shape that went wrong; "traced": traced_sample, each pixel's path recorded), or over the whole
// image as a 1-D launch in groups of 128 (kind "mega-1d"). Says whether it ended; for "traced", how each path ended.
int region(sycl::queue& queue, const SceneView<T>& view, u32 x0, u32 y0, u32 w, u32 h, u32 sample, const std::string& kind, double seconds) {
  const u32 width = view.params.width, height = view.params.height;
  const std::size_t pixels = static_cast<std::size_t>(width) * height;
  FilmPixel* film = sycl::malloc_device<FilmPixel>(pixels, queue);
  queue.memset(film, 0, pixels * sizeof(FilmPixel)).wait();
  const MegakernelSample<T> pass{view, film, sample};
  const MegakernelPass<T> loop_pass{view, film, sample, 1};
  const sycl::range<2> group(8, 16);
  const sycl::range<2> global((h + 7) / 8 * 8, (w + 15) / 16 * 16);
  sycl::event event;
  Trace* traces = nullptr;
  if (kind == "mega-loop") {
    event = queue.parallel_for(sycl::nd_range<2>(global, group), [=](sycl::nd_item<2> item) {
      const u32 x = static_cast<u32>(item.get_global_id(1)), y = static_cast<u32>(item.get_global_id(0));
      if (x < w && y < h && x0 + x < width && y0 + y < height) loop_pass(x0 + x, y0 + y);
    });
  } else if (kind == "mega") {
    event = queue.parallel_for(sycl::nd_range<2>(global, group), [=](sycl::nd_item<2> item) {
      const u32 x = static_cast<u32>(item.get_global_id(1)), y = static_cast<u32>(item.get_global_id(0));
      if (x < w && y < h && x0 + x < width && y0 + y < height) pass(x0 + x, y0 + y);
    });
  } else if (kind == "mega-1d") {
    const std::size_t items = (pixels + 127) / 128 * 128;
    event = queue.parallel_for(sycl::nd_range<1>(items, 128), [=](sycl::nd_item<1> item) {
      const std::size_t i = item.get_global_id(0);
      if (i < pixels) pass(static_cast<u32>(i % width), static_cast<u32>(i / width));
    });
  } else if (kind == "traced") {
    traces = sycl::malloc_host<Trace>(static_cast<std::size_t>(w) * h, queue);
    std::memset(static_cast<void*>(traces), 0, sizeof(Trace) * w * h);
    event = queue.parallel_for(sycl::nd_range<2>(global, group), [=](sycl::nd_item<2> item) {
      const u32 x = static_cast<u32>(item.get_global_id(1)), y = static_cast<u32>(item.get_global_id(0));
      if (x < w && y < h) traced_sample(view, x0 + x, y0 + y, sample, &traces[y * w + x]);
    });
  } else {
    std::fprintf(stderr, "unknown kind %s\n", kind.c_str());
    return 2;
  }
  const bool ended = wait_for(event, seconds);
  std::printf("%s launch of sample %u over %ux%u at (%u, %u): %s\n", kind.c_str(), sample, w, h, x0, y0, ended ? "ended" : "HAS NOT ENDED");
  if (traces) {
    for (u32 i = 0; i < w * h; ++i) {
      const Trace& t = traces[i];
      const u32 n = __atomic_load_n(&t.records, __ATOMIC_ACQUIRE);
      const Record& last = t.record[n > 0 ? n - 1 : 0];
      std::printf("  pixel (%u, %u): %u records, last: bounce %u stage %u visits %u\n", x0 + i % w, y0 + i / w, n, last.bounce, last.stage,
                  last.visits);
    }
    for (u32 i = 0; i < w * h; ++i) {
      const u32 n = __atomic_load_n(&traces[i].records, __ATOMIC_ACQUIRE);
      if (n > 0 && (traces[i].record[n - 1].stage == 6 || traces[i].record[n - 1].stage == 1)) print_trace("unfinished path", traces[i]);
    }
  }
  std::fflush(stdout);
  if (!ended) std::_Exit(3);
  return 0;
}

int trace(sycl::queue& queue, const FlatScene<T>& flat, const SceneView<T>& view, u32 x, u32 y, u32 sample, double seconds) {
  Trace* host_trace = new Trace{};
  traced_sample(flat.view(), x, y, sample, host_trace);
  print_trace("host", *host_trace);
  // The host's walk: the binary one, as on the device.
  Trace* device_trace = sycl::malloc_host<Trace>(1, queue);
  std::memset(device_trace, 0, sizeof(Trace));
  const sycl::event event = queue.parallel_for(sycl::range<1>(1), [=](sycl::item<1>) { traced_sample(view, x, y, sample, device_trace); });
  const bool ended = wait_for(event, seconds);
  print_trace(ended ? "device" : "device (the launch has not ended)", *device_trace);
  if (!ended) std::_Exit(3);
  // The same path: the same steps, bounces and primitives (positions may differ in the last bits where the
  // device contracts multiply-adds).
  bool same = host_trace->records == device_trace->records;
  for (u32 i = 0; same && i < host_trace->records && i < kMaxRecords; ++i) {
    const Record& a = host_trace->record[i];
    const Record& b = device_trace->record[i];
    same = a.stage == b.stage && a.bounce == b.bounce && (a.stage == 1 || a.stage == 3 || a.primitive == b.primitive);
    if (!same) std::printf("the paths part at record %u\n", i);
  }
  std::printf("%s\n", same ? "the device's path is the host's" : "the device's path is not the host's");
  return same ? 0 : 4;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 7) {
    std::fprintf(stderr, "usage: %s find SCENE WIDTH HEIGHT FIRST LAST [SECONDS] | trace SCENE WIDTH HEIGHT X Y SAMPLE [SECONDS]\n", argv[0]);
    return 2;
  }
  const std::string mode = argv[1];
  const SceneDescription scene = load_scene_file(argv[2]);
  RenderSettings settings = scene.render;
  settings.width = static_cast<u32>(std::atoi(argv[3]));
  settings.height = static_cast<u32>(std::atoi(argv[4]));
  const FlatScene<T> flat = flatten_scene<T>(scene, settings);
  sycl::queue queue = gpu_queue();
  std::printf("device: %s\n", queue.get_device().get_info<sycl::info::device::name>().c_str());
  const SceneView<T> view = place_scene(flat, [&](const auto& array, const char*) { return upload(queue, array); });
  if (mode == "find")
    return find(queue, view, static_cast<u32>(std::atoi(argv[5])), static_cast<u32>(std::atoi(argv[6])), argc > 7 ? std::atof(argv[7]) : 5.0);
  if (mode == "trace" && argc >= 8)
    return trace(queue, flat, view, static_cast<u32>(std::atoi(argv[5])), static_cast<u32>(std::atoi(argv[6])), static_cast<u32>(std::atoi(argv[7])),
                 argc > 8 ? std::atof(argv[8]) : 5.0);
  if (mode == "region" && argc >= 12)
    return region(queue, view, static_cast<u32>(std::atoi(argv[5])), static_cast<u32>(std::atoi(argv[6])), static_cast<u32>(std::atoi(argv[7])),
                  static_cast<u32>(std::atoi(argv[8])), static_cast<u32>(std::atoi(argv[9])), argv[10], std::atof(argv[11]));
  std::fprintf(stderr, "unknown mode %s\n", mode.c_str());
  return 2;
}
