// The Host check and bearer tokens (server/access.hpp), without a server.
#include <gtest/gtest.h>

#include "access.hpp"
#include "http_message.hpp"

namespace umbra {
namespace {

HttpRequest request_with(HttpHeaders headers, int minor_version = 1, std::string target = "/api/scenes") {
  HttpRequest r;
  r.method = "GET";
  r.target = std::move(target);
  r.path = "/api/scenes";
  r.minor_version = minor_version;
  r.headers = std::move(headers);
  return r;
}

TEST(Access, HostOfTakesTheHostWithoutItsPort) {
  EXPECT_EQ(host_of("localhost:8080"), "localhost");
  EXPECT_EQ(host_of("Render.Example"), "render.example");
  EXPECT_EQ(host_of("localhost."), "localhost");
  EXPECT_EQ(host_of("127.0.0.1:"), "127.0.0.1");
  EXPECT_EQ(host_of("[::1]:8080"), "[::1]");
  EXPECT_EQ(host_of("[::1]"), "[::1]");
  EXPECT_EQ(host_of("a:65535"), "a");
  for (const char* bad : {"", ":80", "a b", "a/b", "x:port", "[::1", "[::1]x", "[]", "a:123456", "a:65536", "a:99999", "évil", "a@b"})
    EXPECT_FALSE(host_of(bad)) << bad;
}

TEST(Access, LoopbackAddresses) {
  for (const char* h : {"127.0.0.1", "127.1.2.3", "localhost", "LOCALHOST", "::1", "[::1]"})
    EXPECT_TRUE(is_loopback_address(h)) << h;
  for (const char* h : {"0.0.0.0", "::", "10.0.0.5", "127.0.0", "127.0.0.1.5", "127.0.0.256", "127.evil.example",
                        "render.example", ""})
    EXPECT_FALSE(is_loopback_address(h)) << h;
}

TEST(Access, ByDefaultLoopbackNamesAndTheBoundAddressAtAnyPort) {
  const AllowedHosts hosts("127.0.0.1", {});
  for (const char* ok : {"localhost", "localhost:8080", "127.0.0.1:1", "[::1]:8080", "LocalHost"})
    EXPECT_FALSE(hosts.check(request_with({{"Host", ok}}))) << ok;
  const AccessRefusal foreign = hosts.check(request_with({{"Host", "evil.example:8080"}}));
  EXPECT_EQ(foreign.status, 421);
  EXPECT_NE(foreign.message.find("'evil.example'"), std::string::npos) << foreign.message;
  EXPECT_EQ(hosts.check(request_with({{"Host", "10.0.0.5"}})).status, 421);
  // A LAN address bound is a name clients use; a wildcard is none.
  EXPECT_FALSE(AllowedHosts("10.0.0.5", {}).check(request_with({{"Host", "10.0.0.5:8080"}})));
  EXPECT_FALSE(AllowedHosts("fd00::5", {}).check(request_with({{"Host", "[fd00::5]:8080"}})));
  EXPECT_EQ(AllowedHosts("0.0.0.0", {}).check(request_with({{"Host", "0.0.0.0"}})).status, 421);
  EXPECT_TRUE(AllowedHosts("0.0.0.0", {}).loopback_only());
  EXPECT_FALSE(AllowedHosts("0.0.0.0", {"render.example"}).loopback_only());
}

TEST(Access, ListedHostsAndTheWildcard) {
  std::vector<std::string> names;
  std::string error;
  ASSERT_TRUE(AllowedHosts::parse_list("Render.Example, 10.0.0.5,[fd00::5]", names, error)) << error;
  EXPECT_EQ(names, (std::vector<std::string>{"render.example", "10.0.0.5", "[fd00::5]"}));
  const AllowedHosts hosts("0.0.0.0", names);
  EXPECT_FALSE(hosts.check(request_with({{"Host", "render.example:443"}})));
  EXPECT_FALSE(hosts.check(request_with({{"Host", "[fd00::5]"}})));
  EXPECT_EQ(hosts.check(request_with({{"Host", "other.example"}})).status, 421);
  ASSERT_TRUE(AllowedHosts::parse_list("*", names, error));
  EXPECT_FALSE(AllowedHosts("0.0.0.0", names).check(request_with({{"Host", "anything.example"}})));
  EXPECT_FALSE(AllowedHosts::parse_list("render.example:8080", names, error));
  EXPECT_NE(error.find("without a port"), std::string::npos) << error;
  EXPECT_FALSE(AllowedHosts::parse_list("a,,b", names, error));
  EXPECT_FALSE(AllowedHosts::parse_list("http://a", names, error));
}

// RFC 9112 §3.2.
TEST(Access, AMissingOrRepeatedHostOnHttp11Is400) {
  const AllowedHosts hosts("127.0.0.1", {"*"});  // whatever the name: the field itself is wrong
  EXPECT_EQ(hosts.check(request_with({})).status, 400);
  EXPECT_EQ(hosts.check(request_with({{"Host", "localhost"}, {"host", "localhost"}})).status, 400);
  EXPECT_EQ(hosts.check(request_with({{"Host", ""}})).status, 400);
  EXPECT_EQ(hosts.check(request_with({{"Host", "a b"}})).status, 400);
  // HTTP/1.0 need not send one; if it does, it is checked.
  EXPECT_FALSE(AllowedHosts("127.0.0.1", {}).check(request_with({}, 0)));
  EXPECT_EQ(AllowedHosts("127.0.0.1", {}).check(request_with({{"Host", "evil.example"}}, 0)).status, 421);
}

TEST(Access, AnAbsoluteTargetsAuthorityIsTheHostChecked) {
  const AllowedHosts hosts("127.0.0.1", {});
  EXPECT_EQ(hosts.check(request_with({{"Host", "localhost"}}, 1, "http://evil.example/api/scenes")).status, 421);
  EXPECT_FALSE(hosts.check(request_with({{"Host", "evil.example"}}, 1, "http://user@localhost:8080/api/scenes")));
}

TEST(Access, BearerTokens) {
  EXPECT_EQ(bearer_token("Bearer abc.DEF-123_~+/="), "abc.DEF-123_~+/=");
  EXPECT_EQ(bearer_token("bearer  abc "), "abc");
  for (const char* bad : {"", "Bearer", "Bearer ", "Basic dXNlcjpwYXNz", "Bearer a b", "Bearer a,b", "Bearerabc"})
    EXPECT_FALSE(bearer_token(bad)) << bad;
}

TEST(Access, APrincipalIsTwelveHexDigitsOfTheTokensDigestNeverTheToken) {
  // SHA-256("abc") = ba7816bf8f01cfea414140de5dae2223...
  EXPECT_EQ(token_principal("abc"), "token:ba7816bf8f01");
}

const char* kFile =
    "# render clients\n"
    "render-only-token-0001 render\n"
    "\n"
    "   # an indented comment\n"
    "uploader-token-00000002\trender, upload\r\n"
    "everything-token-000003 render,upload,metrics\n";

TEST(Access, ATokenFileGivesEachTokenItsScopes) {
  std::string error;
  const auto tokens = TokenTable::parse(kFile, error);
  ASSERT_TRUE(tokens) << error;
  EXPECT_EQ(tokens->size(), 3u);
  const TokenTable::Found render = tokens->find("render-only-token-0001");
  EXPECT_TRUE(render.known);
  EXPECT_EQ(render.scopes, unsigned(kScopeRender));
  EXPECT_EQ(render.principal, token_principal("render-only-token-0001"));
  EXPECT_EQ(tokens->find("uploader-token-00000002").scopes, unsigned(kScopeRender | kScopeUpload));
  EXPECT_EQ(tokens->find("everything-token-000003").scopes, unsigned(kScopeRender | kScopeUpload | kScopeMetrics));
  EXPECT_FALSE(tokens->find("render-only-token-0002").known);
  EXPECT_FALSE(tokens->find("").known);
  EXPECT_TRUE(tokens->find("unknown").principal.empty());
}

TEST(Access, AMalformedTokenFileNamesTheLineAndNeverTheToken) {
  struct Case {
    const char* text;
    const char* says;
  };
  const Case cases[] = {
      {"secret-token-0000001\n", "line 1: want TOKEN SCOPE"},
      {"# c\nsecret-token-0000001 render,admin\n", "line 2: unknown scope 'admin'"},
      {"secret-token-0000001 render,\n", "line 1: unknown scope ''"},
      {"\n\nsecret-tok render\n", "line 3: the token is shorter than 16"},
      {"secret\"token\"0000001 render\n", "line 1: a token may hold only"},
      {"secret-token-0000001 render\nsecret-token-0000001 upload\n", "line 2: the same token"},
      {"# nothing\n\n", "no token"},
      {"", "no token"},
  };
  for (const Case& c : cases) {
    std::string error;
    EXPECT_FALSE(TokenTable::parse(c.text, error)) << c.text;
    EXPECT_NE(error.find(c.says), std::string::npos) << error;
    EXPECT_EQ(error.find("secret"), std::string::npos) << error;
  }
}

TEST(Access, AuthorizeIs401WithoutAKnownToken403WithoutTheScope) {
  std::string error, principal;
  const auto tokens = TokenTable::parse(kFile, error);
  ASSERT_TRUE(tokens) << error;
  const auto with = [](const char* authorization) {
    return request_with({{"Host", "localhost"}, {"Authorization", authorization}});
  };
  EXPECT_EQ(authorize(*tokens, request_with({{"Host", "localhost"}}), kScopeRender, "GET /api/scenes", principal).status,
            401);
  EXPECT_EQ(authorize(*tokens, with("Bearer nope-nope-nope-nope"), kScopeRender, "x", principal).status, 401);
  EXPECT_EQ(authorize(*tokens, with("Basic cmVuZGVy"), kScopeRender, "x", principal).status, 401);
  EXPECT_TRUE(principal.empty());
  const AccessRefusal scope = authorize(*tokens, with("Bearer render-only-token-0001"), kScopeUpload, "POST /api/models",
                                        principal);
  EXPECT_EQ(scope.status, 403);
  EXPECT_NE(scope.message.find("POST /api/models needs the upload scope; this token has render"), std::string::npos)
      << scope.message;
  EXPECT_EQ(principal, token_principal("render-only-token-0001")) << "known, if refused";
  EXPECT_FALSE(authorize(*tokens, with("Bearer uploader-token-00000002"), kScopeUpload, "x", principal));
  EXPECT_FALSE(authorize(*tokens, with("Bearer render-only-token-0001"), 0, "x", principal)) << "any known token";
  HttpRequest twice = with("Bearer render-only-token-0001");
  twice.headers.emplace_back("Authorization", "Bearer everything-token-000003");
  EXPECT_EQ(authorize(*tokens, twice, kScopeRender, "x", principal).status, 400);
  for (const std::string& message :
       {authorize(*tokens, with("Bearer nope-nope-nope-nope"), kScopeRender, "x", principal).message,
        authorize(*tokens, with("Bearer render-only-token-0001"), kScopeMetrics, "x", principal).message})
    EXPECT_EQ(message.find("token-0"), std::string::npos) << message;
}

}  // namespace
}  // namespace umbra
