// libFuzzer target: any bytes as what a client sends on a connection. The
// HTTP reader must never crash, hang or hit undefined behaviour; it must
// read the same requests whether the bytes come at once or in pieces (a
// connection delivers them in any split); and what it accepts must hold
// to its limits.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <vector>

#include "http_message.hpp"

namespace {

struct Outcome {
  std::vector<std::string> requests;  // method, target and body of each complete request
  int error = 0;
};

// Reads requests one after another, as a connection does, feeding `pieces`
// bytes at a time (0: all at once).
Outcome read_all(const std::string& bytes, std::size_t pieces, const umbra::HttpLimits& limits) {
  Outcome out;
  umbra::RequestReader reader(limits);
  std::string buffer;
  std::size_t at = 0;
  while (true) {
    const std::size_t n = pieces == 0 ? bytes.size() - at : std::min(pieces, bytes.size() - at);
    buffer.append(bytes, at, n);
    at += n;
    reader.feed(buffer);
    if (reader.state() == umbra::RequestReader::State::Failed) {
      if (reader.error_status() < 400 || reader.error_status() > 505 || reader.error_message().empty()) std::abort();
      out.error = reader.error_status();
      return out;
    }
    if (reader.state() == umbra::RequestReader::State::Complete) {
      const umbra::HttpRequest r = reader.take_request();
      if (r.method.empty() || r.path.empty() || r.body.size() > limits.max_body_bytes) std::abort();
      if (r.target.size() > limits.max_target_bytes || r.headers.size() > limits.max_header_count) std::abort();
      out.requests.push_back(r.method + " " + r.target + "\n" + r.body);
      reader.reset();
      continue;  // a pipelined request may already be buffered
    }
    if (at == bytes.size()) return out;
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  // The first byte picks the split; small limits reach every limit's edge.
  const std::size_t pieces = 1 + data[0] % 7;
  const std::string bytes(reinterpret_cast<const char*>(data) + 1, size - 1);
  umbra::HttpLimits limits;
  limits.max_body_bytes = 64;
  limits.max_target_bytes = 48;
  limits.max_header_count = 6;
  limits.max_header_bytes = 128;
  const Outcome whole = read_all(bytes, 0, limits);
  const Outcome split = read_all(bytes, pieces, limits);
  if (whole.requests != split.requests || whole.error != split.error) std::abort();
  return 0;
}
