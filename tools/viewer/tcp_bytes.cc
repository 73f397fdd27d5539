#include "tools/viewer/tcp_bytes.h"

#include <linux/tcp.h>
#include <netinet/in.h>
#include <stddef.h>
#include <sys/socket.h>

namespace anchormap::viewer {

int64_t TcpBytesAcked(int fd) {
  struct tcp_info info {};
  socklen_t length = sizeof(info);
  if (getsockopt(fd, IPPROTO_TCP, TCP_INFO, &info, &length) != 0) return -1;
  if (length < offsetof(struct tcp_info, tcpi_bytes_acked) + sizeof(info.tcpi_bytes_acked)) {
    return -1;  // an old kernel
  }
  return static_cast<int64_t>(info.tcpi_bytes_acked);
}

}  // namespace anchormap::viewer
