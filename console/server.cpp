#include "console/server.h"

#include <pthread.h>

#include <algorithm>
#include <array>
#include <boost/asio.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <chrono>
#include <deque>
#include <list>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>

#include "core/error.h"
#include "core/json_text.h"

namespace rangebayes {

namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace net = boost::asio;
using tcp = net::ip::tcp;

namespace {
class HttpSession;
class WsSession;
}  // namespace

// Everything the server thread owns. The io_context is destroyed before the members declared above it: its
// destruction destroys the pending handlers and with them the sessions, which then touch only those (a
// session's destructor takes itself off open_sessions).
struct ConsoleServer::State {
  // Guards open_sessions and what Wants() reads of each (written on the server thread only).
  mutable std::mutex demand_mutex;
  std::vector<const WsSession*> open_sessions;
  std::list<std::weak_ptr<HttpSession>> connections;  // HTTP connections in accept order, server thread only
  net::io_context ioc{1};
  ConsoleServerOptions options;
  Handler handler;
  std::optional<tcp::acceptor> acceptor;
  std::optional<net::steady_timer> accept_retry;
  std::vector<std::weak_ptr<WsSession>> sessions;  // server thread only
  std::atomic<bool> stopped{false};
  std::atomic<int> clients{0};
  std::atomic<std::int64_t> queued{0}, sent{0}, dropped{0}, coalesced{0}, requests{0}, refused{0}, idle_closed{0};
};

namespace {

using State = ConsoleServer::State;

struct Outgoing {
  std::shared_ptr<const std::string> data;
  bool binary = true;
  std::string topic;
};

// Subscription groups one client may hold: the server publishes a handful (mesh, depth, ...); a client that names
// more only makes the server remember them (a page sending new names in a loop grew the process without bound).
constexpr size_t kMaxSubscriptionGroups = 16;

// On a loopback address every request must name a loopback host in Host: a page of another site whose DNS name is
// rebound to 127.0.0.1 sends its own name there, and so reads neither the status nor the meshes (the WebSocket
// upgrade was checked alone: the status page and the capture downloads answered such a page). A request without
// Host (an HTTP/1.0 program, not a browser) is let be.
bool HostAllowed(const http::request<http::string_body>& request, const std::string& bound_address) {
  boost::system::error_code ec;
  const net::ip::address bound = net::ip::make_address(bound_address, ec);
  if (ec || !bound.is_loopback()) return true;
  const auto host_field = request.find(http::field::host);
  if (host_field == request.end()) return true;
  const std::string authority(host_field->value());
  const size_t port_colon = authority.rfind(':');
  const bool has_port = port_colon != std::string::npos && authority.find(']', port_colon) == std::string::npos;
  const std::string host = has_port ? authority.substr(0, port_colon) : authority;
  return host == "localhost" || host == "127.0.0.1" || host == "[::1]" || host == bound_address;
}

// A WebSocket upgrade a browser makes for a page of another site is refused: browsers send Origin with every
// upgrade and do not apply the same-origin rule to WebSockets, so any page open in the operator's browser could
// otherwise read the camera images and meshes. Accepted: no Origin (a program, not a browser page), or an Origin
// whose host and port are the request's Host (which HostAllowed has checked).
bool WebSocketOriginAllowed(const http::request<http::string_body>& request) {
  const auto origin_field = request.find(http::field::origin);
  if (origin_field == request.end()) return true;
  const std::string origin(origin_field->value());
  const size_t scheme_end = origin.find("://");
  if (scheme_end == std::string::npos) return false;
  const std::string scheme = origin.substr(0, scheme_end);
  const std::string authority = origin.substr(scheme_end + 3);
  if ((scheme != "http" && scheme != "https") || authority.empty()) return false;
  return authority == std::string(request[http::field::host]);
}

bool TopicWanted(const std::map<std::string, std::string>& subscriptions, const std::string& topic) {
  const size_t slash = topic.find('/');
  if (slash == std::string::npos) return true;
  const auto it = subscriptions.find(topic.substr(0, slash));
  return it == subscriptions.end() || it->second == topic.substr(slash + 1);
}

class WsSession : public std::enable_shared_from_this<WsSession> {
 public:
  WsSession(tcp::socket socket, State* state)
      : ws_(std::move(socket)), state_(state), subscriptions_(state->options.default_subscriptions) {}
  ~WsSession() { Unregister(); }

  void Run(http::request<http::string_body> request) {
    request_ = std::move(request);
    beast::error_code ignored;
    if (state_->options.send_buffer_bytes > 0) {
      beast::get_lowest_layer(ws_).socket().set_option(
          net::socket_base::send_buffer_size(state_->options.send_buffer_bytes), ignored);
    }
    beast::get_lowest_layer(ws_).expires_never();
    ws_.set_option(websocket::stream_base::timeout::suggested(beast::role_type::server));
    ws_.read_message_max(static_cast<std::uint64_t>(state_->options.max_client_message_bytes));
    ws_.async_accept(request_, beast::bind_front_handler(&WsSession::OnAccept, shared_from_this()));
  }

  // Each topic has its own bound, so that a flood of one kind (images) never starves another (status).
  void Enqueue(const Outgoing& message) {
    if (!open_ || !TopicWanted(subscriptions_, message.topic)) return;
    const bool paced = credit_flow_ && message.binary;
    if (paced) {
      if (Unacked(message.topic) >= state_->options.flow_credits) {
        const auto [held, inserted] = held_.try_emplace(message.topic, message);
        if (!inserted) {
          held->second = message;
          ++state_->coalesced;
        }
        return;
      }
      std::lock_guard<std::mutex> lock(state_->demand_mutex);
      ++unacked_[message.topic];
    }
    int same = 0;
    for (const Outgoing& m : queue_) same += m.topic == message.topic ? 1 : 0;
    if (same >= state_->options.client_queue_messages) {
      const auto oldest = std::find_if(queue_.begin(), queue_.end(),
                                       [&](const Outgoing& m) { return m.topic == message.topic; });
      if (paced && oldest->binary) ReturnCredit(message.topic);  // never sent, so never acknowledged
      queue_.erase(oldest);
      ++state_->dropped;
    }
    queue_.push_back(message);
    ++state_->queued;
    if (!writing_) DoWrite();
  }

  // Whether a binary message of `topic` would go out at once (State::demand_mutex held).
  bool WantsLocked(const std::string& topic) const {
    if (!TopicWanted(subscriptions_, topic)) return false;
    if (!credit_flow_) return true;
    const auto it = unacked_.find(topic);
    return it == unacked_.end() || it->second < state_->options.flow_credits;
  }

 private:
  void OnAccept(beast::error_code ec) {
    if (ec) return;
    open_ = true;
    ++state_->clients;
    state_->sessions.push_back(weak_from_this());
    {
      std::lock_guard<std::mutex> lock(state_->demand_mutex);
      state_->open_sessions.push_back(this);
    }
    DoRead();
  }

  void Unregister() {
    std::lock_guard<std::mutex> lock(state_->demand_mutex);
    auto& open = state_->open_sessions;
    open.erase(std::remove(open.begin(), open.end(), this), open.end());
  }

  int Unacked(const std::string& topic) const {
    const auto it = unacked_.find(topic);
    return it == unacked_.end() ? 0 : it->second;
  }

  void ReturnCredit(const std::string& topic) {
    const auto it = unacked_.find(topic);
    if (it == unacked_.end() || it->second == 0) return;  // an acknowledgement of nothing on its way
    {
      std::lock_guard<std::mutex> lock(state_->demand_mutex);
      --it->second;
    }
  }

  void Ack(const std::string& topic) {
    ReturnCredit(topic);
    const auto held = held_.find(topic);
    if (held == held_.end() || Unacked(topic) >= state_->options.flow_credits) return;
    Outgoing next = std::move(held->second);
    held_.erase(held);
    Enqueue(next);
  }

  void DoRead() {
    ws_.async_read(buffer_, beast::bind_front_handler(&WsSession::OnRead, shared_from_this()));
  }

  void OnRead(beast::error_code ec, size_t) {
    if (ec) {
      if (ec == websocket::error::message_too_big) ++state_->refused;
      Closed();
      return;
    }
    const std::string text = beast::buffers_to_string(buffer_.data());
    buffer_.consume(buffer_.size());
    if (!ws_.got_text() || !ApplyClientMessage(text)) {
      ++state_->refused;
      Closed();
      ws_.async_close(websocket::close_reason(websocket::close_code::policy_error, "malformed message"),
                      [self = shared_from_this()](beast::error_code) {});
      return;
    }
    DoRead();
  }

  bool ApplyClientMessage(const std::string& text) {
    const auto message = ParseClientMessage(text);
    if (!message) return false;
    {
      std::lock_guard<std::mutex> lock(state_->demand_mutex);
      for (const auto& [group, value] : message->subscribe) {
        if (subscriptions_.size() >= kMaxSubscriptionGroups && !subscriptions_.contains(group)) return false;
        subscriptions_[group] = value;
      }
      if (message->credit_flow) credit_flow_ = true;
    }
    // A message held back for a topic the client no longer wants would only be stale when it comes back.
    std::erase_if(held_, [&](const auto& held) { return !TopicWanted(subscriptions_, held.first); });
    for (const std::string& topic : message->acks) Ack(topic);
    return true;
  }

  void DoWrite() {
    if (queue_.empty() || !open_) return;
    writing_ = true;
    current_ = std::move(queue_.front());
    queue_.pop_front();
    ws_.binary(current_.binary);
    ws_.async_write(net::buffer(*current_.data), beast::bind_front_handler(&WsSession::OnWrite, shared_from_this()));
  }

  void OnWrite(beast::error_code ec, size_t) {
    writing_ = false;
    current_ = {};
    if (ec) {
      Closed();
      return;
    }
    ++state_->sent;
    DoWrite();
  }

  void Closed() {
    if (open_) --state_->clients;
    open_ = false;
    queue_.clear();
    held_.clear();
    Unregister();
  }

  websocket::stream<beast::tcp_stream> ws_;
  State* state_;
  http::request<http::string_body> request_;
  beast::flat_buffer buffer_;
  // Written on the server thread under State::demand_mutex (Wants() reads them from other threads).
  std::map<std::string, std::string> subscriptions_;
  bool credit_flow_ = false;
  std::map<std::string, int> unacked_;  // credit flow: binary messages per topic sent or queued, not acknowledged
  std::map<std::string, Outgoing> held_;  // credit flow: the newest message per topic waiting for a credit
  std::deque<Outgoing> queue_;
  Outgoing current_;
  bool writing_ = false;
  bool open_ = false;
};

// The status a parser error is answered with; 0 for the errors that only end the connection.
int RefusalStatus(beast::error_code ec, std::string* reason) {
  if (ec == http::error::body_limit) {
    *reason = "request body too large";
    return 413;
  }
  if (ec == http::error::header_limit) {
    *reason = "request header too large";
    return 431;
  }
  *reason = "malformed request";
  return 400;
}

// A complete request checked against the limits and converted for the handler (or marked as an upgrade).
HttpParseResult CheckRequest(const http::request<http::string_body>& req, const ConsoleServerOptions& options) {
  HttpParseResult r;
  r.complete = true;
  if (req.target().size() > static_cast<size_t>(options.max_target_chars)) {
    r.refuse_status = 414;
    r.refuse_reason = "request target too long";
    return r;
  }
  r.request.target = std::string(req.target());
  r.request.method = std::string(req.method_string());
  if (websocket::is_upgrade(req)) {
    r.websocket_upgrade = true;
    return r;
  }
  r.request.body = req.body();
  for (const auto& field : req) {
    std::string name(field.name_string());
    for (char& c : name) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    r.request.headers[name] = std::string(field.value());
  }
  return r;
}

class HttpSession : public std::enable_shared_from_this<HttpSession> {
 public:
  HttpSession(tcp::socket socket, State* state) : stream_(std::move(socket)), state_(state) {}

  void Run() { DoRead(); }

  // Waiting for the next request (or for the rest of one that is arriving), nothing to answer yet.
  bool waiting() const { return waiting_; }

  // Closes the connection; the pending read ends with operation_aborted and the session with it.
  void Close() {
    beast::error_code ignored;
    stream_.socket().close(ignored);
  }

 private:
  void DoRead() {
    waiting_ = true;
    parser_.emplace();
    parser_->header_limit(static_cast<std::uint32_t>(state_->options.max_header_bytes));
    parser_->body_limit(static_cast<std::uint64_t>(state_->options.max_body_bytes));
    stream_.expires_after(std::chrono::seconds(15));
    http::async_read(stream_, buffer_, *parser_, beast::bind_front_handler(&HttpSession::OnRead, shared_from_this()));
  }

  void OnRead(beast::error_code ec, size_t) {
    waiting_ = false;
    if (ec == http::error::end_of_stream || ec == beast::error::timeout || ec == net::error::eof ||
        ec == net::error::connection_reset || ec == net::error::operation_aborted) {
      beast::error_code ignored;
      stream_.socket().shutdown(tcp::socket::shutdown_send, ignored);
      return;
    }
    if (ec) {
      std::string reason;
      const int status = RefusalStatus(ec, &reason);
      return Refuse(status, reason);
    }
    http::request<http::string_body>& req = parser_->get();
    HttpParseResult parsed = CheckRequest(req, state_->options);
    if (parsed.refuse_status != 0) return Refuse(parsed.refuse_status, parsed.refuse_reason);
    if (!HostAllowed(req, state_->options.address)) {
      return Refuse(403,
                    "Host names no loopback host (the console answers on this address to localhost, 127.0.0.1 "
                    "and [::1] only)");
    }
    if (parsed.websocket_upgrade) {
      const std::string path = parsed.request.target.substr(0, parsed.request.target.find('?'));
      if (path != "/ws" || req.method() != http::verb::get) return Refuse(404, "no WebSocket here");
      if (!WebSocketOriginAllowed(req)) return Refuse(403, "WebSocket from another origin");
      if (state_->clients.load() >= state_->options.max_clients) return Refuse(503, "too many clients");
      std::make_shared<WsSession>(stream_.release_socket(), state_)->Run(parser_->release());
      return;
    }
    const HttpRequest& request = parsed.request;
    HttpReply reply;
    try {
      reply = state_->handler(request);
    } catch (const std::exception& e) {
      reply.status = 500;
      reply.body = JsonText(nlohmann::json{{"error", e.what()}});
    }
    if (reply.status >= 400) ++state_->refused;
    Send(reply, !req.keep_alive(), req.version(), req.method() == http::verb::head);
  }

  void Refuse(int status, const std::string& reason) {
    ++state_->refused;
    HttpReply reply;
    reply.status = status;
    reply.body = JsonText(nlohmann::json{{"error", reason}});
    Send(reply, /*close=*/true, 11);
  }

  // head: the answer to a HEAD request, its headers (Content-Length included) without the body.
  void Send(const HttpReply& reply, bool close, unsigned version, bool head = false) {
    ++state_->requests;
    response_ = {};
    response_.version(version);
    response_.result(static_cast<unsigned>(reply.status));
    response_.set(http::field::server, "rangebayes");
    response_.set(http::field::content_type, reply.content_type);
    response_.set(http::field::cache_control, "no-store");
    response_.set("X-Content-Type-Options", "nosniff");
    response_.set("Referrer-Policy", "no-referrer");
    for (const auto& [name, value] : reply.headers) response_.set(name, value);
    response_.body() = reply.body;
    response_.keep_alive(!close);
    response_.prepare_payload();
    if (head) response_.body().clear();
    http::async_write(stream_, response_,
                      beast::bind_front_handler(&HttpSession::OnWrite, shared_from_this(), close));
  }

  void OnWrite(bool close, beast::error_code ec, size_t) {
    if (ec) return;
    if (close) {
      beast::error_code ignored;
      stream_.socket().shutdown(tcp::socket::shutdown_send, ignored);
      // Read and discard what the client still sends (a refused body) for a moment before closing, so that
      // closing with unread data (a reset) does not destroy the answer before the client reads it.
      stream_.expires_after(std::chrono::seconds(2));
      Drain(0);
      return;
    }
    DoRead();
  }

  void Drain(size_t drained) {
    if (drained > (1u << 20)) return;
    stream_.async_read_some(net::buffer(scratch_), [self = shared_from_this(), drained](beast::error_code ec, size_t n) {
      if (!ec) self->Drain(drained + n);
    });
  }

  beast::tcp_stream stream_;
  State* state_;
  beast::flat_buffer buffer_;
  std::optional<http::request_parser<http::string_body>> parser_;
  http::response<http::string_body> response_;
  std::array<char, 4096> scratch_{};
  bool waiting_ = false;
};

// Keeps the HTTP connections within max_connections: at the bound the oldest one waiting for a request is closed.
// When every one is busy answering, the new one is let in (they end within their timeout).
void MakeRoomForConnection(State* state) {
  auto& connections = state->connections;
  connections.remove_if([](const std::weak_ptr<HttpSession>& c) { return c.expired(); });
  if (static_cast<int>(connections.size()) < state->options.max_connections) return;
  for (auto it = connections.begin(); it != connections.end(); ++it) {
    const std::shared_ptr<HttpSession> c = it->lock();
    if (c && c->waiting()) {
      c->Close();
      connections.erase(it);
      ++state->idle_closed;
      return;
    }
  }
}

void DoAccept(State* state) {
  state->acceptor->async_accept(state->ioc, [state](beast::error_code ec, tcp::socket socket) {
    if (ec == net::error::operation_aborted) return;
    if (ec) {
      // Out of file descriptors, or another failure of the moment: the connection stays in the backlog, so an
      // accept at once would fail at once, in a loop that takes a whole core. Try again a moment later.
      state->accept_retry->expires_after(std::chrono::milliseconds(100));
      state->accept_retry->async_wait([state](beast::error_code wait_ec) {
        if (!wait_ec) DoAccept(state);
      });
      return;
    }
    MakeRoomForConnection(state);
    auto connection = std::make_shared<HttpSession>(std::move(socket), state);
    state->connections.push_back(connection);
    connection->Run();
    DoAccept(state);
  });
}

}  // namespace

HttpParseResult ParseHttpRequest(std::string_view bytes, const ConsoleServerOptions& options) {
  http::request_parser<http::string_body> parser;
  parser.header_limit(static_cast<std::uint32_t>(options.max_header_bytes));
  parser.body_limit(static_cast<std::uint64_t>(options.max_body_bytes));
  parser.eager(true);
  size_t used = 0;
  while (!parser.is_done() && used < bytes.size()) {
    beast::error_code ec;
    const size_t n = parser.put(net::buffer(bytes.data() + used, bytes.size() - used), ec);
    used += n;
    if (ec == http::error::need_more) {
      if (n == 0) break;
      continue;
    }
    if (ec) {
      HttpParseResult r;
      r.complete = true;
      r.refuse_status = RefusalStatus(ec, &r.refuse_reason);
      r.consumed = used;
      return r;
    }
    if (n == 0) break;
  }
  if (!parser.is_done()) {
    HttpParseResult r;
    r.consumed = used;
    return r;
  }
  HttpParseResult r = CheckRequest(parser.get(), options);
  r.consumed = used;
  return r;
}

std::optional<ClientMessage> ParseClientMessage(std::string_view text) {
  const nlohmann::json j = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded() || !j.is_object() || j.empty()) return std::nullopt;
  ClientMessage out;
  for (const auto& [key, value] : j.items()) {
    if (key == "subscribe") {
      if (!value.is_object() || value.size() > 8) return std::nullopt;
      for (const auto& [group, v] : value.items()) {
        if (!v.is_string() || group.size() > 32 || v.get<std::string>().size() > 32) return std::nullopt;
        out.subscribe[group] = v.get<std::string>();
      }
    } else if (key == "flow") {
      if (value != "credit") return std::nullopt;
      out.credit_flow = true;
    } else if (key == "ack") {
      const nlohmann::json topics = value.is_array() ? value : nlohmann::json::array({value});
      if (topics.size() > 8) return std::nullopt;
      for (const nlohmann::json& t : topics) {
        if (!t.is_string() || t.get<std::string>().size() > 32) return std::nullopt;
        out.acks.push_back(t.get<std::string>());
      }
    } else {
      return std::nullopt;
    }
  }
  return out;
}

void ConsoleServerOptions::Check() const {
  RB_CHECK(port >= 0 && port <= 65535, "console port must be in 0..65535, got ", port);
  RB_CHECK(max_header_bytes >= 512, "console: max_header_bytes must be >= 512");
  RB_CHECK(max_body_bytes >= 0, "console: max_body_bytes must be >= 0");
  RB_CHECK(max_target_chars >= 16, "console: max_target_chars must be >= 16");
  RB_CHECK(max_client_message_bytes >= 64, "console: max_client_message_bytes must be >= 64");
  RB_CHECK(client_queue_messages >= 1, "console: client_queue_messages must be >= 1");
  RB_CHECK(max_clients >= 1, "console: max_clients must be >= 1");
  RB_CHECK(max_connections >= 1, "console: max_connections must be >= 1");
  RB_CHECK(flow_credits >= 1, "console: flow_credits must be >= 1");
  RB_CHECK(send_buffer_bytes >= 0, "console: send_buffer_bytes must be >= 0");
}

ConsoleServer::ConsoleServer(const ConsoleServerOptions& options, Handler handler)
    : options_(options), state_(std::make_unique<State>()) {
  options.Check();
  state_->options = options;
  state_->handler = std::move(handler);
  beast::error_code ec;
  const net::ip::address address = net::ip::make_address(options.address, ec);
  RB_CHECK(!ec, "console: '", options.address, "' is not a numeric IP address");
  const tcp::endpoint endpoint(address, static_cast<unsigned short>(options.port));
  state_->acceptor.emplace(state_->ioc);
  state_->acceptor->open(endpoint.protocol(), ec);
  RB_CHECK(!ec, "console: cannot open a socket: ", ec.message());
  state_->acceptor->set_option(net::socket_base::reuse_address(true), ec);
  state_->acceptor->bind(endpoint, ec);
  RB_CHECK(!ec, "console: cannot listen on ", options.address, ":", options.port, ": ", ec.message());
  state_->acceptor->listen(net::socket_base::max_listen_connections, ec);
  RB_CHECK(!ec, "console: cannot listen on ", options.address, ":", options.port, ": ", ec.message());
  port_ = state_->acceptor->local_endpoint().port();
  state_->accept_retry.emplace(state_->ioc);
  DoAccept(state_.get());
  thread_ = std::thread([state = state_.get()] {
    pthread_setname_np(pthread_self(), "rb-console-net");
    for (;;) {
      try {
        state->ioc.run();
        return;
      } catch (const std::exception&) {
        // A handler failed in a way the sessions did not catch: keep serving the others.
      }
    }
  });
}

ConsoleServer::~ConsoleServer() { Stop(); }

void ConsoleServer::Stop() {
  if (state_->stopped.exchange(true)) return;
  net::post(state_->ioc, [state = state_.get()] {
    beast::error_code ignored;
    state->acceptor->close(ignored);
  });
  state_->ioc.stop();
  if (thread_.joinable()) thread_.join();
}

void ConsoleServer::Broadcast(std::shared_ptr<const std::string> message, bool binary, const std::string& topic) {
  if (state_->stopped.load()) return;
  net::post(state_->ioc, [state = state_.get(), message = std::move(message), binary, topic] {
    const Outgoing out{message, binary, topic};
    auto& sessions = state->sessions;
    size_t kept = 0;
    for (size_t i = 0; i < sessions.size(); ++i) {
      if (auto s = sessions[i].lock()) {
        s->Enqueue(out);
        sessions[kept++] = sessions[i];
      }
    }
    sessions.resize(kept);
  });
}

bool ConsoleServer::Wants(const std::string& topic) const {
  std::lock_guard<std::mutex> lock(state_->demand_mutex);
  for (const WsSession* s : state_->open_sessions) {
    if (s->WantsLocked(topic)) return true;
  }
  return false;
}

ConsoleServerStats ConsoleServer::stats() const {
  ConsoleServerStats s;
  s.clients = state_->clients.load();
  s.messages_queued = state_->queued.load();
  s.messages_sent = state_->sent.load();
  s.messages_dropped = state_->dropped.load();
  s.messages_coalesced = state_->coalesced.load();
  s.requests = state_->requests.load();
  s.refused = state_->refused.load();
  s.idle_closed = state_->idle_closed.load();
  return s;
}

}  // namespace rangebayes
