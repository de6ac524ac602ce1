// Whether the client that sent a request is still there, asked of the
// connection's socket (HttpRequest::socket) from any thread.
#pragma once

namespace umbra {

/// True if the peer has closed (or reset) the connection on `socket`: it
/// will never read an answer. Data waiting to be read (a pipelined request)
/// does not count as closed. Never blocks.
bool peer_closed(int socket);

}  // namespace umbra
