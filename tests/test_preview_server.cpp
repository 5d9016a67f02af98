// The live preview's server as a browser meets it: what it serves, what it refuses, its frames, its actions, and
// pages that come, go and watch the render end (the page itself is tested in a real browser: tests/preview/).
#include <gtest/gtest.h>
#include <httplib.h>

#include <sys/socket.h>
#include <netinet/in.h>
#include <arpa/inet.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <thread>

#include <nlohmann/json.hpp>

#include "base/errors.hpp"
#include "preview/preview_server.hpp"

namespace pt::preview_server_test {
namespace {

// A small film whose pixels differ, so that a frame's bytes say which film they came from.
std::vector<FilmPixel> test_film(u32 width, u32 height, u32 samples, double scale) {
  std::vector<FilmPixel> film(static_cast<std::size_t>(width) * height);
  for (std::size_t i = 0; i < film.size(); ++i) {
    film[i].r = scale * samples * static_cast<double>(i % 7) / 7;
    film[i].g = scale * samples * static_cast<double>(i % 5) / 5;
    film[i].b = scale * samples * static_cast<double>(i % 3) / 3;
    film[i].samples = samples;
  }
  return film;
}

httplib::Client client_of(const PreviewServer& server) {
  httplib::Client client("127.0.0.1", server.port());
  client.set_connection_timeout(5);
  client.set_read_timeout(10);
  return client;
}

int status_of(const httplib::Result& result) { return result ? result->status : -1; }

TEST(PreviewServer, ServesThePageTheStateAndTheFrameOnly) {
  PreviewServer server("127.0.0.1", 0, "test scene");
  httplib::Client client = client_of(server);
  const auto page = client.Get("/");
  ASSERT_EQ(status_of(page), 200);
  EXPECT_NE(page->body.find("<canvas"), std::string::npos);
  EXPECT_EQ(page->get_header_value("Cache-Control"), "no-store");
  const auto status = client.Get("/status");
  ASSERT_EQ(status_of(status), 200);
  const nlohmann::json state = nlohmann::json::parse(status->body);
  EXPECT_EQ(state["title"], "test scene");
  EXPECT_EQ(state["state"], "rendering");
  EXPECT_EQ(state["frame"], 0);
  EXPECT_EQ(status_of(client.Get("/frame.png")), 404) << "no frame before the first pass";
}

TEST(PreviewServer, AnswersEverythingUnexpectedWithA4xx) {
  PreviewServer server("127.0.0.1", 0, "test scene");
  httplib::Client client = client_of(server);
  for (const char* path : {"/index.html", "/../../etc/passwd", "/frame.png/../status", "/scenes/cornell-box.json", "//etc/passwd", "/%2e%2e/etc"})
    EXPECT_EQ(status_of(client.Get(path)), 404) << path;
  EXPECT_EQ(status_of(client.Get("/status?file=/etc/passwd")), 400);
  EXPECT_EQ(status_of(client.Get("/frame.png?frame=1")), 400);
  EXPECT_EQ(status_of(client.Post("/")), 404);
  EXPECT_EQ(status_of(client.Put("/save", "", "text/plain")), 404);
  EXPECT_EQ(status_of(client.Delete("/frame.png")), 404);
  EXPECT_EQ(status_of(client.Post("/stop", httplib::Headers{{"X-Pathtracer-Action", "stop"}}, "x", "text/plain")), 400) << "a body";
  // Actions without the page's header (a form or a script of another site) are refused and change nothing.
  EXPECT_EQ(status_of(client.Post("/stop")), 403);
  EXPECT_EQ(status_of(client.Post("/save", httplib::Headers{{"X-Pathtracer-Action", "stop"}}, "", "text/plain")), 403);
  EXPECT_FALSE(server.stop_requested());
  EXPECT_FALSE(server.take_save_request());
  // A request addressed to another name (a site whose name was made to resolve to 127.0.0.1) is refused.
  EXPECT_EQ(status_of(client.Get("/status", httplib::Headers{{"Host", "attacker.example:" + std::to_string(server.port())}})), 403);
  EXPECT_EQ(status_of(client.Get("/status", httplib::Headers{{"Host", "localhost:" + std::to_string(server.port())}})), 200);
}

// A frame is the PNG the program would write of the film (rows stored, not compressed).
std::string expected_png(const std::vector<FilmPixel>& film, u32 width, u32 height) {
  const std::vector<u8> png = encode_png(rows_of(resolve_film(film, width, height)), 0);
  return std::string(png.begin(), png.end());
}

TEST(PreviewServer, FrameIsThePngOfTheFilmShown) {
  PreviewServer server("127.0.0.1", 0, "test scene");
  httplib::Client client = client_of(server);
  const std::vector<FilmPixel> film = test_film(13, 7, 4, 0.25);
  server.show(film, 13, 7, PreviewProgress{4, 16, 1.5, 1000});
  const auto frame = client.Get("/frame.png");
  ASSERT_EQ(status_of(frame), 200);
  EXPECT_EQ(frame->get_header_value("Content-Type"), "image/png");
  EXPECT_EQ(frame->get_header_value("X-Frame"), "1");
  EXPECT_EQ(frame->get_header_value("X-Frame-Samples"), "4");
  EXPECT_EQ(frame->body, expected_png(film, 13, 7));
  const nlohmann::json state = nlohmann::json::parse(client.Get("/status")->body);
  EXPECT_EQ(state["frame"], 1);
  EXPECT_EQ(state["samples_done"], 4);
  EXPECT_EQ(state["samples_total"], 16);
  EXPECT_NEAR(state["seconds_left"].get<double>(), 4.5, 1e-9);  // three quarters to go at the pace of the first
  // The next frame replaces it.
  const std::vector<FilmPixel> later = test_film(13, 7, 8, 0.5);
  server.show(later, 13, 7, PreviewProgress{8, 16, 3, 1000});
  const auto second = client.Get("/frame.png");
  ASSERT_EQ(status_of(second), 200);
  EXPECT_EQ(second->get_header_value("X-Frame"), "2");
  EXPECT_EQ(second->body, expected_png(later, 13, 7));
}

TEST(PreviewServer, ActionsReachTheRenderOnceAndNotAfterItEnds) {
  PreviewServer server("127.0.0.1", 0, "test scene");
  httplib::Client client = client_of(server);
  EXPECT_FALSE(server.watched());
  EXPECT_EQ(status_of(client.Post("/save", httplib::Headers{{"X-Pathtracer-Action", "save"}}, "", "text/plain")), 200);
  EXPECT_TRUE(server.take_save_request());
  EXPECT_FALSE(server.take_save_request()) << "one press, one save";
  EXPECT_FALSE(server.stop_requested());
  EXPECT_EQ(status_of(client.Post("/stop", httplib::Headers{{"X-Pathtracer-Action", "stop"}}, "", "text/plain")), 200);
  EXPECT_TRUE(server.stop_requested());
  EXPECT_TRUE(nlohmann::json::parse(client.Get("/status")->body)["stop_requested"].get<bool>());
  EXPECT_TRUE(server.watched());
  server.finish(PreviewState::kStopped, "wrote out.png", 0.0);
  const nlohmann::json state = nlohmann::json::parse(client.Get("/status")->body);
  EXPECT_EQ(state["state"], "stopped");
  EXPECT_EQ(state["message"], "wrote out.png");
  EXPECT_EQ(status_of(client.Post("/save", httplib::Headers{{"X-Pathtracer-Action", "save"}}, "", "text/plain")), 409);
}

// Several pages poll at once while frames come, and one connection drops in the middle of a request: every page
// keeps getting answers.
TEST(PreviewServer, ServesSeveralPagesAndOutlivesOneThatLeaves) {
  PreviewServer server("127.0.0.1", 0, "test scene");
  std::atomic<bool> rendering{true};
  std::atomic<int> failures{0}, frames{0};
  std::vector<std::thread> pages;
  for (int p = 0; p < 6; ++p)
    pages.emplace_back([&] {
      httplib::Client client = client_of(server);
      while (rendering.load()) {
        if (status_of(client.Get("/status")) != 200) failures += 1;
        const auto frame = client.Get("/frame.png");
        if (status_of(frame) == 200) frames += 1;
        else if (status_of(frame) != 404) failures += 1;
      }
    });
  // A page that leaves half-way through its request.
  const int sock = ::socket(AF_INET, SOCK_STREAM, 0);
  ASSERT_GE(sock, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(server.port());
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(::connect(sock, reinterpret_cast<const sockaddr*>(&address), sizeof(address)), 0);
  const std::string half = "GET /frame.png HTTP/1.1\r\nHost: 127.0.0.1:" + std::to_string(server.port()) + "\r\n";
  ASSERT_EQ(::send(sock, half.data(), half.size(), MSG_NOSIGNAL), static_cast<ssize_t>(half.size()));
  ::close(sock);
  for (u32 pass = 1; pass <= 20; ++pass) {
    const std::vector<FilmPixel> film = test_film(64, 48, pass, 0.1);
    server.show(film, 64, 48, PreviewProgress{pass, 20, pass * 0.01, 1000});
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  rendering = false;
  for (std::thread& page : pages) page.join();
  EXPECT_EQ(failures.load(), 0);
  EXPECT_GT(frames.load(), 6);
  httplib::Client client = client_of(server);
  EXPECT_EQ(status_of(client.Get("/status")), 200);
}

// The render ends while a page watches: the server waits until the page has been told and has fetched the last
// frame, and no longer; with nobody watching it does not wait at all.
TEST(PreviewServer, EndWaitsForAWatchingPageToSeeIt) {
  {
    PreviewServer server("127.0.0.1", 0, "test scene");
    const auto start = std::chrono::steady_clock::now();
    server.finish(PreviewState::kFinished, "wrote out.png", 10.0);
    EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 1.0);
  }
  PreviewServer server("127.0.0.1", 0, "test scene");
  const std::vector<FilmPixel> film = test_film(8, 8, 2, 1);
  server.show(film, 8, 8, PreviewProgress{2, 2, 0.1, 100});
  std::atomic<bool> told{false};
  std::thread page([&] {
    httplib::Client client = client_of(server);
    while (true) {
      const auto status = client.Get("/status");
      if (status_of(status) != 200) return;
      const nlohmann::json state = nlohmann::json::parse(status->body);
      if (state["state"] == "finished") {
        told = status_of(client.Get("/frame.png")) == 200;
        return;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  const auto start = std::chrono::steady_clock::now();
  server.finish(PreviewState::kFinished, "wrote out.png", 10.0);
  const double waited = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  page.join();
  EXPECT_TRUE(told.load());
  EXPECT_LT(waited, 5.0);
}

// A page asks for the state with the version it has seen: the answer comes when there is news (a pass), not
// before; and a page waiting so counts as watching.
TEST(PreviewServer, StateRequestWaitsForNews) {
  PreviewServer server("127.0.0.1", 0, "test scene");
  httplib::Client client = client_of(server);
  const nlohmann::json first = nlohmann::json::parse(client.Get("/status")->body);
  const std::string seen = std::to_string(first["version"].get<u64>());
  std::thread pass([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(2500));
    EXPECT_TRUE(server.watched()) << "a page waiting for news watches, though its last request began 2.5 s ago";
    server.report(PreviewProgress{3, 10, 1, 100});
  });
  const auto start = std::chrono::steady_clock::now();
  const auto news = client.Get("/status", httplib::Headers{{"X-Pathtracer-Seen", seen}});
  const double waited = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  pass.join();
  ASSERT_EQ(status_of(news), 200);
  EXPECT_GT(waited, 2.0);
  EXPECT_LT(waited, 8.0);
  const nlohmann::json state = nlohmann::json::parse(news->body);
  EXPECT_EQ(state["samples_done"], 3);
  EXPECT_GT(state["version"].get<u64>(), first["version"].get<u64>());
  // An old version is answered at once.
  const auto again = std::chrono::steady_clock::now();
  EXPECT_EQ(status_of(client.Get("/status", httplib::Headers{{"X-Pathtracer-Seen", seen}})), 200);
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - again).count(), 1.0);
}

TEST(PreviewServer, BusyPortIsOneClearError) {
  PreviewServer first("127.0.0.1", 0, "test scene");
  try {
    PreviewServer second("127.0.0.1", first.port(), "test scene");
    FAIL() << "two servers on one port";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("cannot listen on 127.0.0.1 port " + std::to_string(first.port())), std::string::npos) << e.what();
  }
  EXPECT_THROW(PreviewServer("203.0.113.7", 0, "test scene"), InputError) << "not an address of this machine";
}

}  // namespace
}  // namespace pt::preview_server_test
