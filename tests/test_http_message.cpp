// HTTP/1.1 framing (server/http_message.hpp): what a request is, where it
// ends, and which status refuses it. Pure: bytes in, requests out.
#include <gtest/gtest.h>

#include <string>

#include "http_message.hpp"

namespace umbra {
namespace {

using State = RequestReader::State;

// Feeds `bytes` whole; returns what is left over.
std::string feed_all(RequestReader& reader, std::string bytes) {
  reader.feed(bytes);
  return bytes;
}

// The status a request is refused with, or 0 if it is read whole.
int refusal(const std::string& bytes, HttpLimits limits = {}) {
  RequestReader reader(limits);
  feed_all(reader, bytes);
  if (reader.state() == State::Failed) return reader.error_status();
  EXPECT_EQ(reader.state(), State::Complete) << bytes.substr(0, 200);
  return 0;
}

std::string post_head(const std::string& extra) {
  return "POST /api/render HTTP/1.1\r\nHost: x\r\n" + extra + "\r\n";
}

TEST(HttpMessage, AGetIsReadWithItsPathDecodedAndItsQueryApart) {
  RequestReader reader;
  const std::string rest = feed_all(reader, "GET /a%20b/c.html?x=1 HTTP/1.1\r\nHost: x\r\nX-Thing:  v  \r\n\r\n");
  ASSERT_EQ(reader.state(), State::Complete);
  EXPECT_TRUE(rest.empty());
  const HttpRequest& r = reader.request();
  EXPECT_EQ(r.method, "GET");
  EXPECT_EQ(r.target, "/a%20b/c.html?x=1");
  EXPECT_EQ(r.path, "/a b/c.html");
  EXPECT_EQ(r.header("x-thing"), "v");
  EXPECT_TRUE(r.keep_alive);
  EXPECT_TRUE(r.body.empty());
}

TEST(HttpMessage, ByteAtATimeReadsTheSameAsAllAtOnce) {
  const std::string bytes = post_head("Transfer-Encoding: chunked\r\n") + "3;ext=1\r\nabc\r\n2\r\nde\r\n0\r\nT: 1\r\n\r\n";
  RequestReader reader;
  std::string buffer;  // what the reader leaves (a lone CR) waits for the next byte, as on a connection
  for (char c : bytes) {
    ASSERT_NE(reader.state(), State::Complete);
    buffer += c;
    reader.feed(buffer);
    EXPECT_LE(buffer.size(), 1u);
  }
  EXPECT_TRUE(buffer.empty());
  ASSERT_EQ(reader.state(), State::Complete);
  EXPECT_EQ(reader.request().body, "abcde");
  // Trailer fields are read and dropped.
  EXPECT_FALSE(reader.request().has_header("T"));
}

TEST(HttpMessage, PipelinedRequestsAreReadOneAtATimeInOrder) {
  std::string input = "GET /1 HTTP/1.1\r\n\r\nPOST /2 HTTP/1.1\r\nContent-Length: 2\r\n\r\nhiGET /3 HTTP/1.1\r\n\r\n";
  RequestReader reader;
  for (const char* path : {"/1", "/2", "/3"}) {
    reader.feed(input);
    ASSERT_EQ(reader.state(), State::Complete) << path;
    EXPECT_EQ(reader.take_request().path, path);
    reader.reset();
  }
  EXPECT_TRUE(input.empty());
}

TEST(HttpMessage, BlankLinesBeforeARequestAreIgnored) {
  RequestReader reader;
  feed_all(reader, "\r\n\r\n");
  EXPECT_EQ(reader.state(), State::Idle);
  feed_all(reader, "GET / HTTP/1.1\r\n\r\n");
  EXPECT_EQ(reader.state(), State::Complete);
}

TEST(HttpMessage, AChunkedBodyIsRefusedAtTheChunkThatPassesTheLimit) {
  HttpLimits limits;
  limits.max_body_bytes = 1000;
  // One chunk announced past the limit: refused before any of its data.
  EXPECT_EQ(refusal(post_head("Transfer-Encoding: chunked\r\n") + "3e9\r\n", limits), 413);
  // Many small chunks: refused at the one that passes the limit.
  std::string small = post_head("Transfer-Encoding: chunked\r\n");
  for (int i = 0; i < 100; ++i) small += "a\r\n0123456789\r\n";  // 100 x 10 bytes: exactly the limit
  EXPECT_EQ(refusal(small + "0\r\n\r\n", limits), 0);
  EXPECT_EQ(refusal(small + "1\r\nx\r\n", limits), 413);
  // A size with more hex digits than any body can have.
  EXPECT_EQ(refusal(post_head("Transfer-Encoding: chunked\r\n") + "0000000000000000001\r\n"), 413);
  EXPECT_EQ(refusal(post_head("Transfer-Encoding: chunked\r\n") + "ffffffffffffffffffff\r\n"), 413);
}

TEST(HttpMessage, AContentLengthPastTheLimitIsRefusedBeforeItsBody) {
  HttpLimits limits;
  limits.max_body_bytes = 1000;
  EXPECT_EQ(refusal(post_head("Content-Length: 1001\r\n"), limits), 413);
  EXPECT_EQ(refusal(post_head("Content-Length: 99999999999999999999999999999\r\n")), 413);
  RequestReader reader(limits);
  feed_all(reader, post_head("Content-Length: 1000\r\n"));
  EXPECT_EQ(reader.state(), State::Body);
}

TEST(HttpMessage, ARouteMayHaveABodyLimitOfItsOwn) {
  HttpLimits limits;
  limits.max_body_bytes = 10;
  limits.body_limit_for = [](const HttpRequest& head) { return head.path == "/upload" ? 100u : 10u; };
  const std::string body(50, 'x');
  const auto post = [&](const std::string& path, const std::string& framing) {
    return "POST " + path + " HTTP/1.1\r\n" + framing + "\r\n";
  };
  EXPECT_EQ(refusal(post("/upload", "Content-Length: 50\r\n") + body, limits), 0);
  EXPECT_EQ(refusal(post("/other", "Content-Length: 50\r\n") + body, limits), 413);
  EXPECT_EQ(refusal(post("/upload", "Transfer-Encoding: chunked\r\n") + "32\r\n" + body + "\r\n0\r\n\r\n", limits), 0);
  EXPECT_EQ(refusal(post("/other", "Transfer-Encoding: chunked\r\n") + "32\r\n" + body + "\r\n0\r\n\r\n", limits), 413);
  EXPECT_EQ(refusal(post("/upload", "Content-Length: 101\r\n"), limits), 413);
}

TEST(HttpMessage, FramingThatLeavesTheBodyLengthUnknownIs400) {
  for (const char* framing :
       {"Content-Length: 0x10\r\n", "Content-Length: -1\r\n", "Content-Length: +5\r\n", "Content-Length: 5, 5\r\n",
        "Content-Length:\r\n", "Content-Length: 5\r\nContent-Length: 6\r\n",
        "Content-Length: 5\r\nTransfer-Encoding: chunked\r\n", "Transfer-Encoding: gzip\r\n",
        "Transfer-Encoding: gzip, chunked\r\n", "Transfer-Encoding: chunked\r\nTransfer-Encoding: chunked\r\n"})
    EXPECT_EQ(refusal(post_head(framing) + "hello"), 400) << framing;
  // The same length twice is one length.
  EXPECT_EQ(refusal(post_head("Content-Length: 5\r\nContent-Length: 5\r\n") + "hello"), 0);
  EXPECT_EQ(refusal("POST / HTTP/1.0\r\nTransfer-Encoding: chunked\r\n\r\n0\r\n\r\n"), 400);
}

TEST(HttpMessage, MalformedChunksAre400) {
  const std::string head = post_head("Transfer-Encoding: chunked\r\n");
  EXPECT_EQ(refusal(head + "zz\r\n"), 400);
  EXPECT_EQ(refusal(head + "\r\n"), 400);
  EXPECT_EQ(refusal(head + "3 junk\r\n"), 400);
  EXPECT_EQ(refusal(head + "3\r\nabcd\r\n"), 400);  // data longer than its size
  EXPECT_EQ(refusal(head + std::string(5000, '1')), 400);  // a size line past 4 KiB, never ended
  EXPECT_EQ(refusal(head + "1;" + std::string(5000, 'e')), 400);  // a 5 KB extension
}

TEST(HttpMessage, ALongTargetIs414AndTooManyOrTooLargeHeadersAre431) {
  EXPECT_EQ(refusal("GET /" + std::string(4096, 'a') + " HTTP/1.1\r\n\r\n"), 414);
  EXPECT_EQ(refusal("GET /" + std::string(4095, 'a') + " HTTP/1.1\r\n\r\n"), 0);
  // A request line that never ends.
  EXPECT_EQ(refusal("GET /" + std::string(100000, 'a')), 414);
  std::string many = "GET / HTTP/1.1\r\n";
  for (int i = 0; i < 101; ++i) many += "X-" + std::to_string(i) + ": 1\r\n";
  EXPECT_EQ(refusal(many + "\r\n"), 431);
  EXPECT_EQ(refusal("GET / HTTP/1.1\r\nX: " + std::string(33 << 10, 'b') + "\r\n\r\n"), 431);
  // A header line that never ends.
  EXPECT_EQ(refusal("GET / HTTP/1.1\r\nX: " + std::string(100000, 'b')), 431);
  // Trailers count too.
  std::string trailers = post_head("Transfer-Encoding: chunked\r\n") + "0\r\n";
  for (int i = 0; i < 101; ++i) trailers += "T-" + std::to_string(i) + ": 1\r\n";
  EXPECT_EQ(refusal(trailers + "\r\n"), 431);
}

TEST(HttpMessage, MalformedHeadsAre400AndOtherVersions505) {
  for (const char* head :
       {"GET / HTTP/1.1\r\nX: a\rb\r\n\r\n", "GET / HTTP/1.1\r\nX: 1\r\n folded\r\n\r\n", "GET / HTTP/1.1\r\nNoColon\r\n\r\n",
        "GET / HTTP/1.1\r\nX : 1\r\n\r\n", "GET / HTTP/1.1\r\nX: a\001b\r\n\r\n", "GET  / HTTP/1.1\r\n\r\n",
        "GET /\r\n\r\n", "G(T / HTTP/1.1\r\n\r\n", "GET / HTTP/1.1 x\r\n\r\n", "GET / FTP/1.1\r\n\r\n",
        "GET nowhere HTTP/1.1\r\n\r\n", "GET /%zz HTTP/1.1\r\n\r\n", "GET /%4 HTTP/1.1\r\n\r\n"})
    EXPECT_EQ(refusal(head), 400) << head;
  EXPECT_EQ(refusal("GET / HTTP/2.0\r\n\r\n"), 505);
  EXPECT_EQ(refusal("GET / HTTP/0.9\r\n\r\n"), 505);
}

TEST(HttpMessage, ConnectionCloseAndHttp10EndTheConnection) {
  RequestReader a;
  feed_all(a, "GET / HTTP/1.1\r\nConnection: keep-alive, Close\r\n\r\n");
  EXPECT_FALSE(a.request().keep_alive);
  RequestReader b;
  feed_all(b, "GET / HTTP/1.0\r\n\r\n");
  EXPECT_FALSE(b.request().keep_alive);
}

TEST(HttpMessage, AnAbsoluteTargetIsRoutedByItsPath) {
  RequestReader reader;
  feed_all(reader, "GET http://example.com:8080/api/health?x HTTP/1.1\r\n\r\n");
  EXPECT_EQ(reader.request().path, "/api/health");
  RequestReader bare;
  feed_all(bare, "OPTIONS * HTTP/1.1\r\n\r\n");
  EXPECT_EQ(bare.request().path, "*");
}

TEST(HttpMessage, ExpectContinueIsAskedOnceOnlyWhenABodyFollows) {
  RequestReader reader;
  feed_all(reader, post_head("Content-Length: 3\r\nExpect: 100-continue\r\n"));
  EXPECT_EQ(reader.state(), State::Body);
  EXPECT_TRUE(reader.wants_continue());
  reader.continue_sent();
  EXPECT_FALSE(reader.wants_continue());
  feed_all(reader, "abc");
  EXPECT_EQ(reader.request().body, "abc");
  RequestReader empty;
  feed_all(empty, post_head("Content-Length: 0\r\nExpect: 100-continue\r\n"));
  EXPECT_FALSE(empty.wants_continue());
  EXPECT_EQ(refusal(post_head("Content-Length: 3\r\nExpect: 200-ok\r\n") + "abc"), 417);
  // Past the limit: 413 instead of 100 Continue, so the body is never sent.
  EXPECT_EQ(refusal(post_head("Content-Length: 2000000\r\nExpect: 100-continue\r\n")), 413);
}

TEST(HttpMessage, AResponseHeadFramesTheBodyAndNeverBreaksALine) {
  HttpResponse res;
  res.set_content("{}", "application/json");
  res.set_header("X-Quoted", "a\r\nSet-Cookie: evil");
  res.set_header("Content-Length", "999");  // the server's own, not the handler's
  const std::string head = response_head(res, 2, false, 2);
  EXPECT_EQ(head.rfind("HTTP/1.1 200 OK\r\n", 0), 0u);
  EXPECT_NE(head.find("Content-Length: 2\r\n"), std::string::npos);
  EXPECT_EQ(head.find("999"), std::string::npos);
  EXPECT_EQ(head.find("\r\nSet-Cookie"), std::string::npos);
  EXPECT_NE(head.find("Keep-Alive: timeout=2\r\n"), std::string::npos);
  EXPECT_EQ(head.substr(head.size() - 4), "\r\n\r\n");
  HttpResponse none;
  none.status = 204;
  const std::string closing = response_head(none, 0, true, 2);
  EXPECT_EQ(closing.find("Content-Length"), std::string::npos);
  EXPECT_NE(closing.find("Connection: close\r\n"), std::string::npos);
  EXPECT_EQ(closing.find("Keep-Alive"), std::string::npos);
}

}  // namespace
}  // namespace umbra

namespace umbra {
namespace {

TEST(QueryParams, NamesAndValuesDecodedInOrder) {
  std::vector<std::pair<std::string, std::string>> params;
  ASSERT_TRUE(query_params("/api/models?format=ifc&unit=mm&name=a+b%2Fc&flag&&=x#frag", params));
  ASSERT_EQ(params.size(), 5u);
  EXPECT_EQ(params[0], std::make_pair(std::string("format"), std::string("ifc")));
  EXPECT_EQ(params[1], std::make_pair(std::string("unit"), std::string("mm")));
  EXPECT_EQ(params[2], std::make_pair(std::string("name"), std::string("a b/c")));
  EXPECT_EQ(params[3], std::make_pair(std::string("flag"), std::string("")));
  EXPECT_EQ(params[4], std::make_pair(std::string(""), std::string("x")));
  ASSERT_TRUE(query_params("/api/models", params));
  EXPECT_TRUE(params.empty());
  EXPECT_FALSE(query_params("/api/models?format=%zz", params));
  EXPECT_FALSE(query_params("/api/models?format=%4", params));
}

}  // namespace
}  // namespace umbra
