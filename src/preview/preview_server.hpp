// The live preview: a small web server that shows a render converging in a browser (docs/preview.md).
#pragma once

#include <memory>
#include <string>

#include "film/film.hpp"

namespace pt {

// What the page says of the render beside its picture.
struct PreviewProgress {
  u32 samples_done = 0, samples_total = 0;  // per pixel
  double elapsed_seconds = 0;
  double samples_per_second = 0;
};

// How the render stands, for the page: rendering, then one of the ends.
enum class PreviewState { kRendering, kFinished, kStopped, kFailed };

// Serves the page (GET /), the render's state as JSON (GET /status), the newest frame as a PNG (GET /frame.png)
// and two actions (POST /save, POST /stop). Requests never name files; any other request is answered 4xx. Bound to
// loopback, it answers only requests addressed to loopback by name (a page of another site cannot reach it through
// a name of its own), and the actions need a header that only a script of the page's own origin can send.
class PreviewServer {
 public:
  // Listens on `address`:`port` (port 0: any free one) from a thread of its own; throws InputError where it cannot.
  PreviewServer(const std::string& address, unsigned port, std::string title);
  ~PreviewServer();  // stops serving
  PreviewServer(const PreviewServer&) = delete;
  PreviewServer& operator=(const PreviewServer&) = delete;

  unsigned port() const;
  std::string url() const;

  // Whether a page has asked for the state or a frame lately: frames are made only then.
  bool watched() const;
  // A new frame: the film of `progress.samples_done` samples per pixel.
  void show(std::span<const FilmPixel> film, u32 width, u32 height, const PreviewProgress& progress);
  // Progress alone (no new picture).
  void report(const PreviewProgress& progress);
  // A line for the page: what was saved, where.
  void say(std::string message);

  // The page's actions: "save now" (taken once: true once per press) and "stop" (stays set).
  bool take_save_request();
  bool stop_requested() const;

  // The render has ended: the page is told how, and pages watching are given up to `linger_seconds` to fetch the
  // last frame before the server stops.
  void finish(PreviewState state, std::string message, double linger_seconds = 3.0);

 private:
  struct Shared;
  std::unique_ptr<Shared> shared_;
};

}  // namespace pt
