// The HTTP and WebSocket server of the operator's console: Boost.Beast on one Asio thread of its own.
// HTTP requests go to one handler (the console decides what a path means); "GET /ws" with an upgrade becomes
// a WebSocket client. Messages for clients are queued per client and written asynchronously: a client that
// reads slowly or not at all only loses its own oldest queued messages (counted), it never blocks Broadcast.
// A client may instead ask for credit flow (the page does): then at most `flow_credits` binary messages of a
// topic are on their way to it until it acknowledges one it has shown, and a newer message of that topic
// replaces the one held back for it (counted as coalesced), so what it gets next is always the newest.
// Limits: request header and body sizes, target length, WebSocket message size from a client, number of
// clients; a request over a limit is answered 413 (431 for headers) and the connection closed.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <thread>
#include <utility>
#include <vector>

namespace rangebayes {

struct ConsoleServerOptions {
  std::string address = "127.0.0.1";  // numeric IPv4 or IPv6 address to listen on
  int port = 0;                        // 0–65535; 0: any free port (ConsoleServer::port() tells which)
  int max_header_bytes = 8 * 1024;     // ≥ 512: one request's header
  int max_body_bytes = 16 * 1024;      // ≥ 0: one request's body
  int max_target_chars = 512;          // ≥ 16: the request target (path and query)
  int max_client_message_bytes = 1024; // ≥ 64: one WebSocket message from a client (larger: connection closed)
  int client_queue_messages = 2;       // ≥ 1: messages of one topic waiting per client; beyond it the oldest
                                       // of that topic is dropped (a live view wants the newest, not a backlog)
  int max_clients = 16;                // ≥ 1: WebSocket clients at once (more: 503)
  // ≥ 1: HTTP connections at once (WebSocket clients apart). At the bound the oldest connection waiting for a
  // request is closed to make room (a browser opens another when it needs one), so that a flood of idle
  // connections cannot take the file descriptors that the pipeline needs to write its results.
  int max_connections = 64;
  int flow_credits = 1;                // ≥ 1: unacknowledged binary messages of one topic on their way to a
                                       // client that asked for credit flow
  // ≥ 0: SO_SNDBUF of WebSocket sockets (0: the system's, which grows to megabytes: a backlog of stale
  // frames in the kernel, seconds of latency on a slow client). Tests shrink it further.
  int send_buffer_bytes = 256 * 1024;
  // Topics a client receives before it asks for others: topic "group/value" goes to a client that has no
  // subscription for "group" or whose subscription for it is "value"; a topic without '/' goes to everyone.
  std::map<std::string, std::string> default_subscriptions;
  void Check() const;
};

struct HttpRequest {
  std::string method;  // "GET", "POST", ...
  std::string target;  // as sent, e.g. "/api/status?x=1"
  std::string body;
  std::map<std::string, std::string> headers;  // lower-case names
};

struct HttpReply {
  int status = 200;
  std::string content_type = "application/json";
  std::string body;
  std::vector<std::pair<std::string, std::string>> headers;  // extra headers (Content-Disposition, ...)
};

// What the server makes of the bytes of one request before its handler sees them (the server's own parser
// and limits, without a socket; for tests and fuzzing).
struct HttpParseResult {
  bool complete = false;           // a whole request (header and body) was read; false: more bytes needed
  int refuse_status = 0;           // 0: accepted; else the answer before closing: 400 malformed, 413 body,
                                   // 414 target, 431 header too large
  std::string refuse_reason;       // one line, for the answer's body
  bool websocket_upgrade = false;  // an upgrade request (the server's WebSocket path)
  HttpRequest request;             // when complete and accepted
  size_t consumed = 0;             // bytes of the input the request used
};
HttpParseResult ParseHttpRequest(std::string_view bytes, const ConsoleServerOptions& options);

// What a client's WebSocket message asks for. The message is a JSON object with one or more of
//   "subscribe": {"group": "value", ...}  at most 8 groups, names and values of at most 32 bytes;
//   "flow": "credit"                      binary messages from now on paced by acknowledgements;
//   "ack": "topic" or ["topic", ...]      at most 8 topics of at most 32 bytes: one message of each was shown.
struct ClientMessage {
  std::map<std::string, std::string> subscribe;
  bool credit_flow = false;
  std::vector<std::string> acks;
};
// nullopt for any other message (the server then closes the connection with a policy error).
std::optional<ClientMessage> ParseClientMessage(std::string_view text);

struct ConsoleServerStats {
  int clients = 0;
  std::int64_t messages_queued = 0;   // messages handed to clients' queues
  std::int64_t messages_sent = 0;     // completely written to a client
  std::int64_t messages_dropped = 0;  // oldest messages dropped from full client queues
  std::int64_t messages_coalesced = 0;  // held back for a credit-flow client and replaced by a newer one
  std::int64_t requests = 0;          // HTTP requests answered
  std::int64_t refused = 0;           // requests and client messages refused (limits, malformed)
  std::int64_t idle_closed = 0;       // idle HTTP connections closed to make room (max_connections)
};

class ConsoleServer {
 public:
  using Handler = std::function<HttpReply(const HttpRequest&)>;

  // Listens and starts the server thread; throws Error when the address cannot be bound. The handler runs
  // on the server thread and must not block for long; an exception from it is answered 500. The only
  // message a client may send is a JSON object {"subscribe": {"group": "value", ...}} (at most 8 groups);
  // anything else closes its connection (policy error).
  ConsoleServer(const ConsoleServerOptions& options, Handler handler);
  ~ConsoleServer();  // Stop()
  ConsoleServer(const ConsoleServer&) = delete;
  ConsoleServer& operator=(const ConsoleServer&) = delete;

  int port() const { return port_; }
  const std::string& address() const { return options_.address; }

  // Queues `message` (binary or text) for every client subscribed to `topic`. Never blocks; thread-safe.
  void Broadcast(std::shared_ptr<const std::string> message, bool binary, const std::string& topic);
  // Whether a binary message of `topic` broadcast now would be sent to some client at once: one that is
  // subscribed and either takes every message or holds a credit. Lets the caller skip encoding what nobody
  // would see (a credit-flow client that acknowledges later gets the next message). Thread-safe.
  bool Wants(const std::string& topic) const;

  ConsoleServerStats stats() const;
  void Stop();

  struct State;  // server.cpp

 private:
  ConsoleServerOptions options_;
  std::unique_ptr<State> state_;
  std::thread thread_;
  int port_ = 0;
};

}  // namespace rangebayes
