// Loads scene files and prints, for each, the time the load took (reading, parsing and checking it into a scene
// description) and the process's peak memory after it: the scene-loading figures of BENCHMARKS.md.
#include <sys/resource.h>

#include <chrono>
#include <cstdio>
#include <exception>

#include "loading/scene_loader.hpp"

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s SCENE...\n", argv[0]);
    return 2;
  }
  int status = 0;
  for (int i = 1; i < argc; ++i) {
    const auto start = std::chrono::steady_clock::now();
    std::size_t objects = 0;
    try {
      objects = pt::load_scene_file(argv[i]).objects.size();
    } catch (const std::exception& e) {
      std::printf("%s: refused: %s\n", argv[i], e.what());
      status = 1;
    }
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    rusage usage{};
    getrusage(RUSAGE_SELF, &usage);
    std::printf("%s: %zu objects, %.3f s, peak RSS %.0f MB\n", argv[i], objects, seconds, usage.ru_maxrss / 1024.0);
  }
  return status;
}
