// The live preview's server: cpp-httplib serves the page, the state and the frames from a thread pool of its own.
#include "preview/preview_server.hpp"

#include <sys/socket.h>

#include <httplib.h>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <thread>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "base/errors.hpp"
#include "preview/preview_page.hpp"

namespace pt {
namespace {

using Clock = std::chrono::steady_clock;

// A page that asked within this long, or that is waiting for news, is still watching.
constexpr double kWatchingSeconds = 2.0;

// A page asks for the state with the version it has seen (this header); the answer waits until there is a newer one,
// at most this long. So a page wakes once a pass, not on a timer.
constexpr const char* kSeenHeader = "X-Pathtracer-Seen";
constexpr double kLongestWait = 10.0;

// The header the page's scripts send with an action. A form or a link of another site cannot set it, and a script
// of another origin that tries must ask first (a CORS preflight), which is refused.
constexpr const char* kActionHeader = "X-Pathtracer-Action";

const char* state_name(PreviewState state) {
  switch (state) {
    case PreviewState::kRendering: return "rendering";
    case PreviewState::kFinished: return "finished";
    case PreviewState::kStopped: return "stopped";
    case PreviewState::kFailed: return "failed";
  }
  return "rendering";
}

bool is_loopback(const std::string& address) { return address == "127.0.0.1" || address == "::1" || address == "localhost"; }

}  // namespace

struct PreviewServer::Shared {
  httplib::Server server;
  std::thread thread;
  std::string address;
  std::string title;
  unsigned port = 0;

  mutable std::mutex mutex;
  std::condition_variable changed;
  Clock::time_point last_request{};  // by a page: the state or a frame
  bool ever_watched = false;
  int waiting_pages = 0;     // requests for the state waiting for news
  u64 version = 1;           // bumped by every change a page would show
  bool closing = false;      // the server is stopping: waiting requests answer at once
  bool ended_status_sent = false;  // a page has been told how the render ended
  // The newest frame: its number (0: none yet), its samples per pixel and its PNG.
  u64 frame = 0;
  u32 frame_samples = 0;
  std::shared_ptr<const std::vector<u8>> png;
  u64 last_frame_sent = 0;
  PreviewProgress progress;
  PreviewState state = PreviewState::kRendering;
  std::string message;
  bool save_request = false;
  bool stop_request = false;

  nlohmann::json status() const {
    const double fraction = progress.samples_total > 0 ? static_cast<double>(progress.samples_done) / progress.samples_total : 0;
    const double left = state == PreviewState::kRendering && fraction > 0 ? progress.elapsed_seconds * (1 - fraction) / fraction : 0;
    return nlohmann::json{{"version", version},
                          {"title", title},
                          {"state", state_name(state)},
                          {"frame", frame},
                          {"frame_samples", frame_samples},
                          {"samples_done", progress.samples_done},
                          {"samples_total", progress.samples_total},
                          {"elapsed_seconds", progress.elapsed_seconds},
                          {"seconds_left", left},
                          {"samples_per_second", progress.samples_per_second},
                          {"message", message},
                          {"stop_requested", stop_request}};
  }

  void watched_now() {
    last_request = Clock::now();
    ever_watched = true;
  }

  bool watching() const {
    return waiting_pages > 0 || (ever_watched && std::chrono::duration<double>(Clock::now() - last_request).count() < kWatchingSeconds);
  }

  // Called with the mutex held, after a change.
  void changed_now() {
    version += 1;
    changed.notify_all();
  }
};

PreviewServer::PreviewServer(const std::string& address, unsigned port, std::string title) : shared_(std::make_unique<Shared>()) {
  Shared& s = *shared_;
  s.address = address;
  s.title = std::move(title);
  httplib::Server& server = s.server;
  // Few threads: a page makes one request at a time, and the render has the cores.
  // Threads enough for several pages, each holding a request for the state open and fetching a frame.
  server.new_task_queue = [] { return new httplib::ThreadPool(16); };
  server.set_keep_alive_timeout(2);
  server.set_payload_max_length(1024);

  // Every request: addressed to this server by a loopback name where it listens on loopback (a name of another
  // site that resolves here, DNS rebinding, is refused), and without a query (nothing here takes one).
  const bool loopback = is_loopback(address);
  server.set_pre_routing_handler([&s, loopback](const httplib::Request& request, httplib::Response& response) {
    if (loopback) {
      const std::string host = request.get_header_value("Host");
      const std::string port = std::to_string(s.port);
      if (host != "127.0.0.1:" + port && host != "localhost:" + port && host != "[::1]:" + port) {
        response.status = 403;
        response.set_content("this preview answers requests for 127.0.0.1 or localhost only\n", "text/plain");
        return httplib::Server::HandlerResponse::Handled;
      }
    }
    if (!request.params.empty() || request.target.find('?') != std::string::npos) {
      response.status = 400;
      response.set_content("no request here takes a query\n", "text/plain");
      return httplib::Server::HandlerResponse::Handled;
    }
    return httplib::Server::HandlerResponse::Unhandled;
  });
  server.set_error_handler([](const httplib::Request&, httplib::Response& response) {
    if (response.body.empty())
      response.set_content(response.status == 404 ? "no such page: the preview serves /, /status, /frame.png, /save and /stop\n" : "not a request this preview takes\n",
                           "text/plain");
  });
  const auto no_store = [](httplib::Response& response) { response.set_header("Cache-Control", "no-store"); };

  server.Get("/", [&s, no_store](const httplib::Request&, httplib::Response& response) {
    no_store(response);
    response.set_header("Content-Security-Policy", "default-src 'self'; script-src 'unsafe-inline'; style-src 'unsafe-inline'; img-src 'self'");
    response.set_content(std::string(kPreviewPage), "text/html; charset=utf-8");
    (void)s;
  });
  server.Get("/status", [&s, no_store](const httplib::Request& request, httplib::Response& response) {
    std::unique_lock lock(s.mutex);
    s.watched_now();
    const std::string seen = request.get_header_value(kSeenHeader);
    if (!seen.empty() && seen == std::to_string(s.version) && !s.closing) {
      s.waiting_pages += 1;
      s.changed.wait_for(lock, std::chrono::duration<double>(kLongestWait), [&] { return s.closing || std::to_string(s.version) != seen; });
      // A pass reports its progress and then its frame: wait a moment for the frame, so that one answer carries both.
      if (!s.closing) s.changed.wait_for(lock, std::chrono::milliseconds(30), [&] { return s.closing; });
      s.waiting_pages -= 1;
      s.watched_now();
    }
    if (s.state != PreviewState::kRendering) s.ended_status_sent = true;
    no_store(response);
    response.set_content(s.status().dump(), "application/json");
    s.changed.notify_all();
  });
  server.Get("/frame.png", [&s, no_store](const httplib::Request&, httplib::Response& response) {
    std::shared_ptr<const std::vector<u8>> png;
    u64 frame = 0;
    u32 samples = 0;
    {
      std::lock_guard lock(s.mutex);
      s.watched_now();
      frame = s.frame;
      samples = s.frame_samples;
      png = s.png;
      if (png) s.last_frame_sent = std::max(s.last_frame_sent, frame);
    }
    if (!png) {
      response.status = 404;
      response.set_content("no frame yet: the first pass is under way\n", "text/plain");
      return;
    }
    s.changed.notify_all();
    no_store(response);
    response.set_header("X-Frame", std::to_string(frame));
    response.set_header("X-Frame-Samples", std::to_string(samples));
    response.set_content(reinterpret_cast<const char*>(png->data()), png->size(), "image/png");
  });
  const auto action = [&s, no_store](bool save) {
    return [&s, no_store, save](const httplib::Request& request, httplib::Response& response) {
      if (request.get_header_value(kActionHeader) != (save ? "save" : "stop")) {
        response.status = 403;
        response.set_content(fmt::format("an action needs the header {}, which the page sends\n", kActionHeader), "text/plain");
        return;
      }
      if (!request.body.empty()) {
        response.status = 400;
        response.set_content("an action takes no body\n", "text/plain");
        return;
      }
      {
        std::lock_guard lock(s.mutex);
        if (s.state != PreviewState::kRendering) {
          response.status = 409;
          response.set_content("the render has ended\n", "text/plain");
          return;
        }
        (save ? s.save_request : s.stop_request) = true;
        s.changed_now();
      }
      no_store(response);
      response.set_content(save ? "saving after the pass under way\n" : "stopping after the pass under way\n", "text/plain");
    };
  };
  server.Post("/save", action(true));
  server.Post("/stop", action(false));

  // The library's default lets a second server share a port in use (SO_REUSEPORT), which would split one render's
  // pages between two programs: only a port left in TIME_WAIT may be taken again.
  server.set_socket_options([](socket_t socket) {
    const int yes = 1;
    ::setsockopt(socket, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof(yes));
  });
  if (port == 0) {
    const int bound = server.bind_to_any_port(address);
    if (bound <= 0) throw InputError(fmt::format("--preview: cannot listen on {}: no free port, or not an address of this machine", address));
    s.port = static_cast<unsigned>(bound);
  } else {
    if (!server.bind_to_port(address, port))
      throw InputError(fmt::format("--preview {}: cannot listen on {} port {}: in use, or not an address of this machine", port, address, port));
    s.port = port;
  }
  s.thread = std::thread([&server] { server.listen_after_bind(); });
  // stop() before the loop runs would be lost: wait for it.
  while (!server.is_running()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
}

PreviewServer::~PreviewServer() {
  {
    std::lock_guard lock(shared_->mutex);
    shared_->closing = true;
    shared_->changed.notify_all();
  }
  shared_->server.stop();
  if (shared_->thread.joinable()) shared_->thread.join();
}

unsigned PreviewServer::port() const { return shared_->port; }

std::string PreviewServer::url() const {
  const std::string& a = shared_->address;
  const std::string host = a == "0.0.0.0" || a == "::" ? "127.0.0.1" : a.find(':') != std::string::npos ? "[" + a + "]" : a;
  return fmt::format("http://{}:{}/", host, shared_->port);
}

bool PreviewServer::watched() const {
  std::lock_guard lock(shared_->mutex);
  return shared_->watching();
}

// The frame is made here, between passes, while the render's threads wait: resolved a band of rows at a time straight
// into the PNG's bytes, by every core, stored rather than compressed (a page on this machine reads it as fast as
// it would inflate it). A second copy of the film, or work beside the render's threads, would cost more. (Raw
// pixels put on the page's canvas cost the browser as much as decoding this.)
void PreviewServer::show(std::span<const FilmPixel> film, u32 width, u32 height, const PreviewProgress& progress) {
  auto png = std::make_shared<const std::vector<u8>>(encode_png(film_rows(film, width, height), 0));
  std::lock_guard lock(shared_->mutex);
  shared_->png = std::move(png);
  shared_->frame += 1;
  shared_->frame_samples = progress.samples_done;
  shared_->progress = progress;
  shared_->changed_now();
}

void PreviewServer::report(const PreviewProgress& progress) {
  std::lock_guard lock(shared_->mutex);
  shared_->progress = progress;
  shared_->changed_now();
}

void PreviewServer::say(std::string message) {
  std::lock_guard lock(shared_->mutex);
  shared_->message = std::move(message);
  shared_->changed_now();
}

bool PreviewServer::take_save_request() {
  std::lock_guard lock(shared_->mutex);
  return std::exchange(shared_->save_request, false);
}

bool PreviewServer::stop_requested() const {
  std::lock_guard lock(shared_->mutex);
  return shared_->stop_request;
}

void PreviewServer::finish(PreviewState state, std::string message, double linger_seconds) {
  Shared& s = *shared_;
  std::unique_lock lock(s.mutex);
  s.state = state;
  s.message = std::move(message);
  s.changed_now();
  const bool watching = s.watching();
  // A page watching is told how the render ended and fetches the last frame; stop once it has, or after the linger.
  if (watching)
    s.changed.wait_for(lock, std::chrono::duration<double>(linger_seconds), [&] { return s.ended_status_sent && s.last_frame_sent >= s.frame; });
}

}  // namespace pt
