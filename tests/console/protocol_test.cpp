// The console's wire format and small checks: message framing, mesh payloads, the wire-mesh reduction,
// --ui parsing, token comparison, names of recordings made from the page.
#include "console/protocol.h"

#include <gtest/gtest.h>

#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "console/server.h"
#include "core/error.h"
#include "tests/test_meshes.h"

namespace rangebayes {
namespace {

// An n×n vertex grid of spacing 0.01 on the plane z = 1, two triangles per cell.
Mesh Grid(int n) {
  Mesh m = testing::Grid(n - 1, n - 1);
  m.V.leftCols(2) *= 0.01;
  m.V.col(2).setOnes();
  return m;
}

TEST(ConsoleProtocol, MessageRoundTripKeepsHeaderAndAlignsPayload) {
  for (const std::string name : {"a", "ab", "abc", "abcd"}) {  // every header length modulo 4
    const std::string msg = EncodeConsoleMessage(ConsoleMessageType::kMesh, {{"k", name}}, "PAYLOAD!");
    const ConsoleMessage m = DecodeConsoleMessage(msg);
    EXPECT_EQ(m.type, ConsoleMessageType::kMesh);
    EXPECT_EQ(m.header["k"], name);
    EXPECT_EQ(m.payload, "PAYLOAD!");
    EXPECT_EQ((m.payload.data() - msg.data()) % 4, 0);  // Float32Array needs 4-byte alignment
  }
}

TEST(ConsoleProtocol, MalformedMessagesAreRefused) {
  EXPECT_THROW(DecodeConsoleMessage("abc"), Error);
  std::string msg = EncodeConsoleMessage(ConsoleMessageType::kImage, {{"k", 1}}, "x");
  std::string bad_type = msg;
  bad_type[0] = 7;
  EXPECT_THROW(DecodeConsoleMessage(bad_type), Error);
  std::string long_header = msg;
  long_header[4] = static_cast<char>(0xff);
  long_header[5] = static_cast<char>(0xff);
  EXPECT_THROW(DecodeConsoleMessage(long_header), Error);
  std::string bad_json = msg;
  bad_json[8] = '!';
  EXPECT_THROW(DecodeConsoleMessage(bad_json), Error);
}

TEST(ConsoleProtocol, MeshPayloadRoundTripAndRefusals) {
  const Mesh grid = Grid(4);
  const std::string p = EncodeMeshPayload(grid);
  EXPECT_EQ(p.size(), 8 + 12 * 16 + 12 * 18u);
  const Mesh back = DecodeMeshPayload(p);
  EXPECT_EQ(back.F, grid.F);
  EXPECT_LT((back.V - grid.V).cwiseAbs().maxCoeff(), 1e-6);  // float32
  EXPECT_THROW(DecodeMeshPayload(p.substr(0, p.size() - 1)), Error);
  std::string bad_index = p;
  bad_index[p.size() - 4] = 99;  // last face names vertex 99 of 16
  EXPECT_THROW(DecodeMeshPayload(bad_index), Error);
  std::string nan_position = p;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(&nan_position[8 + 4], &nan, 4);            // vertex 0, y
  EXPECT_THROW(DecodeMeshPayload(nan_position), Error);  // fuzz_ws_message: no NaN in what is accepted
}

TEST(ConsoleProtocol, WireMeshKeepsSmallMeshesAndReducesLargeOnes) {
  const Mesh small = Grid(10);
  const Mesh same = WireMesh(small);
  EXPECT_EQ(same.F, small.F);
  EXPECT_EQ(same.V, small.V);
  const Mesh large = Grid(201);  // 80,000 faces
  WireMeshOptions o;
  o.max_faces = 5000;
  const Mesh wire = WireMesh(large, o);
  // The cell size comes from the area: on a plane about max_faces remain (cells cut by the grid: ±30%).
  EXPECT_GT(wire.num_faces(), 3500);
  EXPECT_LT(wire.num_faces(), 6500);
  EXPECT_LT((wire.V.col(2).array() - 1.0).abs().maxCoeff(), 1e-12);  // vertices stay on the plane
  EXPECT_GE(wire.V.col(0).minCoeff(), 0.0);
  EXPECT_LE(wire.V.col(0).maxCoeff(), 2.0);
  for (int f = 0; f < wire.num_faces(); ++f) {
    EXPECT_NE(wire.F(f, 0), wire.F(f, 1));
    EXPECT_NE(wire.F(f, 1), wire.F(f, 2));
    EXPECT_NE(wire.F(f, 0), wire.F(f, 2));
  }
}

TEST(ConsoleProtocol, UiAddress) {
  EXPECT_EQ(ParseUiAddress("8080").address, "127.0.0.1");
  EXPECT_EQ(ParseUiAddress("8080").port, 8080);
  EXPECT_EQ(ParseUiAddress("0.0.0.0:9000").address, "0.0.0.0");
  EXPECT_EQ(ParseUiAddress("0.0.0.0:9000").port, 9000);
  EXPECT_EQ(ParseUiAddress("127.0.0.1:0").port, 0);
  EXPECT_EQ(ParseUiAddress("[::1]:8093").address, "::1");
  EXPECT_EQ(ParseUiAddress("[::1]:8093").port, 8093);
  EXPECT_TRUE(IsLoopbackAddress("127.0.0.1"));
  EXPECT_TRUE(IsLoopbackAddress("::1"));
  EXPECT_FALSE(IsLoopbackAddress("0.0.0.0"));
  EXPECT_FALSE(IsLoopbackAddress("192.168.1.2"));
  EXPECT_THROW(ParseUiAddress("http"), Error);
  EXPECT_THROW(ParseUiAddress("70000"), Error);
  EXPECT_THROW(ParseUiAddress(":80"), Error);
  EXPECT_THROW(ParseUiAddress("1.2.3.4:"), Error);
}

TEST(ConsoleProtocol, TokensAndNames) {
  const std::string t = MakeConsoleToken();
  EXPECT_EQ(t.size(), 32u);
  EXPECT_NE(t, MakeConsoleToken());
  EXPECT_TRUE(ConstantTimeEqual(t, t));
  EXPECT_FALSE(ConstantTimeEqual(t, t.substr(0, 31)));
  EXPECT_FALSE(ConstantTimeEqual(t, t + "0"));
  EXPECT_FALSE(ConstantTimeEqual(t, ""));
  std::string other = t;
  other[31] = other[31] == 'a' ? 'b' : 'a';
  EXPECT_FALSE(ConstantTimeEqual(t, other));
  EXPECT_TRUE(IsValidRecordingName("session_1-a.b"));
  for (const std::string& bad : std::vector<std::string>{"", "..", "../x", ".hidden", "a/b", "a\\b", "x y", std::string(65, 'a')}) {
    EXPECT_FALSE(IsValidRecordingName(bad)) << bad;
  }
}

// The server's request parser and limits without a socket (what fuzz_http_request drives).
TEST(ConsoleRequestParser, AcceptsRefusesOrWaitsForMore) {
  const ConsoleServerOptions o;
  const HttpParseResult get = ParseHttpRequest("GET /api/status?x=1 HTTP/1.1\r\nHost: a\r\nX-Thing: V\r\n\r\n", o);
  EXPECT_TRUE(get.complete);
  EXPECT_EQ(get.refuse_status, 0);
  EXPECT_EQ(get.request.method, "GET");
  EXPECT_EQ(get.request.target, "/api/status?x=1");
  EXPECT_EQ(get.request.headers.at("x-thing"), "V");
  EXPECT_FALSE(get.websocket_upgrade);
  const HttpParseResult post = ParseHttpRequest("POST /api/control HTTP/1.1\r\nContent-Length: 4\r\n\r\nbody", o);
  EXPECT_EQ(post.request.body, "body");
  EXPECT_FALSE(ParseHttpRequest("GET / HTTP/1.1\r\nHost: a\r\n", o).complete);  // header not finished
  EXPECT_EQ(ParseHttpRequest("GARBAGE\r\n\r\n", o).refuse_status, 400);
  EXPECT_EQ(ParseHttpRequest("GET /" + std::string(600, 'a') + " HTTP/1.1\r\n\r\n", o).refuse_status, 414);
  EXPECT_EQ(ParseHttpRequest("GET / HTTP/1.1\r\nX: " + std::string(9000, 'a') + "\r\n\r\n", o).refuse_status, 431);
  EXPECT_EQ(ParseHttpRequest("POST / HTTP/1.1\r\nContent-Length: 99999\r\n\r\n", o).refuse_status, 413);
  const HttpParseResult upgrade = ParseHttpRequest(
      "GET /ws HTTP/1.1\r\nHost: a\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
      "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n",
      o);
  EXPECT_TRUE(upgrade.websocket_upgrade);
}

TEST(ConsoleRequestParser, ClientMessagesAreSubscriptionsFlowAndAcksOrNothing) {
  const auto s = ParseClientMessage(R"({"subscribe": {"image": "left", "mesh": "smoothed"}})");
  ASSERT_TRUE(s.has_value());
  EXPECT_EQ(s->subscribe.at("image"), "left");
  EXPECT_FALSE(s->credit_flow);
  const auto f = ParseClientMessage(R"({"subscribe": {"mesh": "raw"}, "flow": "credit", "ack": "image/left"})");
  ASSERT_TRUE(f.has_value());
  EXPECT_TRUE(f->credit_flow);
  EXPECT_EQ(f->acks, std::vector<std::string>{"image/left"});
  const auto a = ParseClientMessage(R"({"ack": ["image/left", "mesh/raw"]})");
  ASSERT_TRUE(a.has_value());
  EXPECT_EQ(a->acks.size(), 2u);
  EXPECT_FALSE(ParseClientMessage(R"({"flow": "window"})").has_value());
  EXPECT_FALSE(ParseClientMessage(R"({"ack": 3})").has_value());
  EXPECT_FALSE(ParseClientMessage(R"({"ack": ["1", "2", "3", "4", "5", "6", "7", "8", "9"]})").has_value());
  EXPECT_FALSE(ParseClientMessage("{}").has_value());
  EXPECT_FALSE(ParseClientMessage("not json").has_value());
  EXPECT_FALSE(ParseClientMessage(R"({"subscribe": {"image": 3}})").has_value());
  EXPECT_FALSE(ParseClientMessage(R"({"subscribe": {}, "x": 1})").has_value());
  EXPECT_FALSE(ParseClientMessage(R"({"subscribe": {"a": "1", "b": "1", "c": "1", "d": "1", "e": "1", "f": "1", )"
                                  R"("g": "1", "h": "1", "i": "1"}})")
                   .has_value());
}

}  // namespace
}  // namespace rangebayes
