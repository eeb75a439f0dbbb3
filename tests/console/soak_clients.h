// Misbehaving WebSocket clients for the console's soak test and bench (loopback only, bounded in time by
// their owner): each runs on its own thread until Stop(), in one of four ways, and counts what it got.
#pragma once

#include <atomic>
#include <boost/asio.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/websocket.hpp>
#include <chrono>
#include <memory>
#include <string>
#include <thread>
#include <vector>

namespace rangebayes::soak {

enum class ClientKind {
  kReader,        // reads every message as fast as it can
  kSlowReader,    // reads one message every 50 ms
  kNeverReads,    // handshakes, then never reads (smallest socket buffer)
  kDisconnector,  // reads part of a message's bytes off the socket, then closes it; connects again
};

class SoakClients {
 public:
  SoakClients(int port, int count) {
    for (int i = 0; i < count; ++i) {
      const ClientKind kind = static_cast<ClientKind>(i % 4);
      threads_.emplace_back([this, port, kind] { Run(port, kind); });
    }
  }
  ~SoakClients() { Stop(); }
  SoakClients(const SoakClients&) = delete;
  SoakClients& operator=(const SoakClients&) = delete;

  void Stop() {
    stop_ = true;
    for (std::thread& t : threads_) {
      if (t.joinable()) t.join();
    }
  }
  std::int64_t messages_read() const { return messages_read_; }
  std::int64_t disconnects() const { return disconnects_; }
  std::int64_t failures() const { return failures_; }  // connections that failed (refused, reset at handshake)

 private:
  using tcp = boost::asio::ip::tcp;

  void Run(int port, ClientKind kind) {
    namespace net = boost::asio;
    namespace websocket = boost::beast::websocket;
    const tcp::endpoint server(net::ip::make_address("127.0.0.1"), static_cast<unsigned short>(port));
    while (!stop_) {
      try {
        net::io_context ioc;
        websocket::stream<tcp::socket> ws(ioc);
        ws.next_layer().open(tcp::v4());
        if (kind == ClientKind::kNeverReads) {
          ws.next_layer().set_option(net::socket_base::receive_buffer_size(1024));
        }
        ws.next_layer().connect(server);
        ws.handshake("127.0.0.1", "/ws");
        if (kind == ClientKind::kNeverReads) {
          while (!stop_) std::this_thread::sleep_for(std::chrono::milliseconds(20));
          return;
        }
        if (kind == ClientKind::kDisconnector) {
          // Part of a frame off the raw socket, then an abrupt close (no WebSocket close handshake).
          std::array<char, 700> part{};
          boost::system::error_code ec;
          ws.next_layer().read_some(net::buffer(part), ec);
          ws.next_layer().close(ec);
          ++disconnects_;
          std::this_thread::sleep_for(std::chrono::milliseconds(30));
          continue;
        }
        // Readers: a short read timeout so that Stop() is seen.
        ws.next_layer().non_blocking(false);
        boost::beast::flat_buffer buffer;
        while (!stop_) {
          boost::system::error_code ec;
          if (!ws.next_layer().available(ec)) {
            std::this_thread::sleep_for(std::chrono::milliseconds(5));
            continue;
          }
          ws.read(buffer, ec);
          if (ec) break;
          buffer.consume(buffer.size());
          ++messages_read_;
          if (kind == ClientKind::kSlowReader) std::this_thread::sleep_for(std::chrono::milliseconds(50));
        }
        return;
      } catch (const std::exception&) {
        ++failures_;
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
      }
    }
  }

  std::vector<std::thread> threads_;
  std::atomic<bool> stop_{false};
  std::atomic<std::int64_t> messages_read_{0}, disconnects_{0}, failures_{0};
};

// Resident memory of this process in bytes (/proc/self/statm), 0 when unknown.
inline std::int64_t ResidentBytes() {
  FILE* f = std::fopen("/proc/self/statm", "r");
  if (f == nullptr) return 0;
  long pages = 0, resident = 0;
  const int n = std::fscanf(f, "%ld %ld", &pages, &resident);
  std::fclose(f);
  return n == 2 ? static_cast<std::int64_t>(resident) * 4096 : 0;
}

}  // namespace rangebayes::soak
