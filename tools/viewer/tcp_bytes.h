#pragma once
// Bytes a TCP socket's peer has acknowledged (Linux TCP_INFO's tcpi_bytes_acked): what
// really went over the wire, after compression and framing. In a file of its own since
// <linux/tcp.h> does not mix with the <netinet/tcp.h> that Asio includes.

#include <cstdint>

namespace anchormap::viewer {

// -1 when the socket cannot tell.
int64_t TcpBytesAcked(int fd);

}  // namespace anchormap::viewer
