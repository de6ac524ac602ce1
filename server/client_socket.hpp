// Whether the client that sent a request is still there.
//
// cpp-httplib 0.11 (Debian 12's) does not hand a handler its socket. It
// serves each connection on one worker thread, though, and the request names
// both ends of the connection, so the socket is the one open descriptor whose
// addresses match; it stays open until the handler returns.
#pragma once

#include <string>

namespace umbra {

/// The descriptor of the connected TCP socket from remote_addr:remote_port to
/// this process's local_port, or -1 if none is open. Remembered per thread,
/// so a keep-alive connection is looked up once.
int find_client_socket(const std::string& remote_addr, int remote_port, int local_port);

/// True if the peer has closed (or reset) the connection on `socket`: it
/// will never read an answer. Data waiting to be read (a pipelined request)
/// does not count as closed. Never blocks.
bool peer_closed(int socket);

}  // namespace umbra
