#include "tests/lcm_recorder.h"

#include <lcm/lcm.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <utility>

#include "common/bus/lcm_loop.h"

namespace anchormap {

namespace {
// The kernel doubles the request for its bookkeeping and caps it at net.core.rmem_max.
constexpr const char* kReceiveBuffer = "recv_buf_size=4194304";
}  // namespace

std::string WithLargeReceiveBuffer(const std::string& url) {
  std::string base = url;
  if (base.empty()) {
    const char* from_environment = std::getenv("LCM_DEFAULT_URL");
    base = from_environment && *from_environment ? from_environment : "udpm://239.255.76.67:7667";
  }
  if (base.find("recv_buf_size=") != std::string::npos) return base;
  // Only udpm:// reads recv_buf_size; other providers take their own options.
  if (base.rfind("udpm://", 0) != 0) return base;
  return base + (base.find('?') == std::string::npos ? "?" : "&") + kReceiveBuffer;
}

struct LcmRecorder::Lcm {
  lcm_t* lcm = nullptr;
  ~Lcm() {
    if (lcm) lcm_destroy(lcm);
  }
  static void OnMessage(const lcm_recv_buf_t* buffer, const char* channel, void* user) {
    static_cast<LcmRecorder*>(user)->Write(buffer->recv_utime, channel, buffer->data,
                                           static_cast<size_t>(buffer->data_size));
  }
};

LcmRecorder::LcmRecorder() : lcm_(std::make_unique<Lcm>()) {}
LcmRecorder::~LcmRecorder() = default;

Result<std::unique_ptr<LcmRecorder>> LcmRecorder::Open(const std::string& url,
                                                       const std::string& channels,
                                                       const std::string& output) {
  std::unique_ptr<LcmRecorder> recorder(new LcmRecorder());
  const std::string full_url = WithLargeReceiveBuffer(url);
  recorder->lcm_->lcm = lcm_create(full_url.c_str());
  if (!recorder->lcm_->lcm) {
    return Status::Error(ErrorCode::kIoError, "cannot open LCM at '" + full_url + "'");
  }
  if (Status opened = recorder->writer_.Open(output); !opened.ok()) return opened;
  lcm_subscription_t* subscription =
      lcm_subscribe(recorder->lcm_->lcm, channels.c_str(), &Lcm::OnMessage, recorder.get());
  if (!subscription) return Status::Error("cannot subscribe to '" + channels + "'");
  // 0: no limit (lcm.c keeps a message while the queue holds <= capacity or capacity <= 0).
  lcm_subscription_set_queue_capacity(subscription, 0);
  return recorder;
}

void LcmRecorder::Write(int64_t receive_utime, const char* channel, const void* data, size_t size) {
  if (!write_status_.ok()) return;
  write_status_ = writer_.WriteRaw(channel, receive_utime, data, size);
  if (!write_status_.ok()) return;
  ++counts_.events;
  counts_.bytes += static_cast<int64_t>(size);
  ++counts_.events_per_channel[channel];
}

Result<int64_t> LcmRecorder::RecordWaiting(int timeout_ms) {
  const int first = lcm_handle_timeout(lcm_->lcm, timeout_ms);
  if (first < 0) {
    if (errno == EINTR) return int64_t{0};  // a signal: the caller looks at its flag
    return Status::Error(ErrorCode::kIoError,
                         std::string("waiting for LCM failed: ") + std::strerror(errno));
  }
  if (first == 0) return int64_t{0};
  int64_t handled = 1;
  while (lcm_handle_timeout(lcm_->lcm, 0) > 0) ++handled;
  counts_.longest_backlog = std::max(counts_.longest_backlog, handled);
  if (!write_status_.ok()) return write_status_;
  if (Status flushed = writer_.Flush(); !flushed.ok()) return flushed;
  return handled;
}

Status LcmRecorder::Run(const volatile std::sig_atomic_t* stop) {
  while (!*stop) {
    const Result<int64_t> recorded = RecordWaiting(100);
    if (!recorded.ok()) return recorded.status();
  }
  // What LCM's receive thread already took off the socket is written too (lcm-logger loses
  // it): until nothing comes for 50 ms, at most 2 s on a bus that does not fall silent.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(2);
  while (std::chrono::steady_clock::now() < deadline) {
    const Result<int64_t> recorded = RecordWaiting(50);
    if (!recorded.ok()) return recorded.status();
    if (*recorded == 0) break;
  }
  counts_.kernel_drops = ReadOwnUdpDrops();
  if (Status flushed = writer_.Flush(); !flushed.ok()) return flushed;
  writer_.Close();
  return Status::Ok();
}

}  // namespace anchormap
