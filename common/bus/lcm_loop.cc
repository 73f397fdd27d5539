#include "common/bus/lcm_loop.h"

#include <lcm/lcm.h>

#include <csignal>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include <boost/asio/posix/stream_descriptor.hpp>
#include <boost/asio/signal_set.hpp>
#include <boost/asio/steady_timer.hpp>

#include "common/util/log.h"
#include "common/util/options_loader.h"

namespace anchormap {

void AddLcmUrlOption(OptionsLoader* loader, std::string* lcm_url) {
  loader->Add("lcm_url", "lcm-url", lcm_url, "LCM URL (empty: $LCM_DEFAULT_URL or LCM's default)");
}
namespace asio = boost::asio;

namespace {
// Messages dispatched per wake-up before timers get a turn (fairness, not a limit: the
// descriptor stays readable and the loop comes straight back).
constexpr int64_t kMaxMessagesPerWakeup = 256;
}  // namespace

class LcmLoop::Impl {
 public:
  struct Subscription {
    RawHandler handler;
    Impl* impl = nullptr;
    lcm_subscription_t* lcm_subscription = nullptr;
  };

  ~Impl() {
    for (auto& timer : timers) timer->cancel();
    if (signals) signals->cancel();
    if (descriptor) {
      descriptor->cancel();
      descriptor->release();  // LCM owns the descriptor and closes it in lcm_destroy
    }
    descriptor.reset();
    signals.reset();
    timers.clear();
    if (lcm) lcm_destroy(lcm);
  }

  static void OnMessage(const lcm_recv_buf_t* buffer, const char* channel, void* user) {
    auto* subscription = static_cast<Subscription*>(user);
    ++subscription->impl->stats.messages_handled;
    // An exception must not unwind through LCM's C code; a handler that throws loses only
    // its message.
    try {
      subscription->handler(channel, static_cast<const uint8_t*>(buffer->data),
                            static_cast<size_t>(buffer->data_size));
    } catch (const std::exception& error) {
      LogError(std::string("handler for ") + channel + " threw: " + error.what());
    }
  }

  void ArmRead() {
    descriptor->async_wait(asio::posix::stream_descriptor::wait_read,
                           [this](const boost::system::error_code& error) {
                             if (error) return;  // cancelled at shutdown
                             DrainReady();
                             ArmRead();
                           });
  }

  void DrainReady() {
    ++stats.wakeups;
    int64_t burst = 0;
    while (burst < kMaxMessagesPerWakeup && lcm_handle_timeout(lcm, 0) > 0) ++burst;
    if (burst > stats.max_burst) stats.max_burst = burst;
  }

  void ArmTimer(asio::steady_timer* timer, std::chrono::milliseconds period,
                std::function<void()>* tick) {
    timer->expires_after(period);
    timer->async_wait([this, timer, period, tick](const boost::system::error_code& error) {
      if (error) return;
      try {
        (*tick)();
      } catch (const std::exception& e) {
        LogError(std::string("timer callback threw: ") + e.what());
      }
      ArmTimer(timer, period, tick);
    });
  }

  asio::io_context io;
  lcm_t* lcm = nullptr;
  std::unique_ptr<asio::posix::stream_descriptor> descriptor;
  std::unique_ptr<asio::signal_set> signals;
  std::vector<std::unique_ptr<Subscription>> subscriptions;
  std::vector<std::unique_ptr<asio::steady_timer>> timers;
  std::vector<std::unique_ptr<std::function<void()>>> ticks;
  LcmLoopStats stats;
};

LcmLoop::LcmLoop() : impl_(std::make_unique<Impl>()) {}
LcmLoop::~LcmLoop() = default;

Result<std::unique_ptr<LcmLoop>> LcmLoop::Create(const std::string& url) {
  std::unique_ptr<LcmLoop> loop(new LcmLoop());
  loop->impl_->lcm = lcm_create(url.empty() ? nullptr : url.c_str());
  if (!loop->impl_->lcm) {
    return Status::Error(
        ErrorCode::kIoError,
        "cannot open LCM at '" + (url.empty() ? std::string("default") : url) + "'");
  }
  const int fd = lcm_get_fileno(loop->impl_->lcm);
  if (fd < 0) {
    return Status::Error(ErrorCode::kIoError,
                         "LCM provider of '" + url + "' has no file descriptor");
  }
  loop->impl_->descriptor = std::make_unique<asio::posix::stream_descriptor>(loop->impl_->io, fd);
  loop->impl_->ArmRead();
  return loop;
}

asio::io_context& LcmLoop::io() { return impl_->io; }

Status LcmLoop::Subscribe(const std::string& channel, RawHandler handler, int queue_capacity) {
  auto subscription = std::make_unique<Impl::Subscription>();
  subscription->handler = std::move(handler);
  subscription->impl = impl_.get();
  subscription->lcm_subscription =
      lcm_subscribe(impl_->lcm, channel.c_str(), &Impl::OnMessage, subscription.get());
  if (!subscription->lcm_subscription) {
    return Status::Error("cannot subscribe to '" + channel + "'");
  }
  if (queue_capacity > 0) {
    lcm_subscription_set_queue_capacity(subscription->lcm_subscription, queue_capacity);
  }
  impl_->subscriptions.push_back(std::move(subscription));
  return Status::Ok();
}

Status LcmLoop::Publish(const std::string& channel, const std::vector<uint8_t>& bytes) {
  if (lcm_publish(impl_->lcm, channel.c_str(), bytes.data(),
                  static_cast<unsigned int>(bytes.size())) != 0) {
    ++impl_->stats.publish_failures;
    return Status::Error("publish on '" + channel + "' failed");
  }
  return Status::Ok();
}

void LcmLoop::Every(std::chrono::milliseconds period, std::function<void()> tick) {
  impl_->timers.push_back(std::make_unique<asio::steady_timer>(impl_->io));
  impl_->ticks.push_back(std::make_unique<std::function<void()>>(std::move(tick)));
  impl_->ArmTimer(impl_->timers.back().get(), period, impl_->ticks.back().get());
}

void LcmLoop::StopOnSignals(std::function<void(int)> on_signal) {
  impl_->signals = std::make_unique<asio::signal_set>(impl_->io, SIGINT, SIGTERM);
  impl_->signals->async_wait(
      [this, on_signal = std::move(on_signal)](const boost::system::error_code& error, int number) {
        if (error) return;
        if (on_signal) on_signal(number);
        Stop();
      });
}

void LcmLoop::RestoreDefaultSignals() {
  // Destroying the signal set unregisters asio's handlers; asio restores the default
  // action of a signal no other set still handles.
  impl_->signals.reset();
}

void LcmLoop::Run() {
  impl_->io.restart();
  impl_->io.run();
}

bool LcmLoop::RunUntil(const std::function<bool()>& done, std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  impl_->io.restart();
  while (!done()) {
    const auto now = std::chrono::steady_clock::now();
    if (now >= deadline || impl_->io.stopped()) return done();
    impl_->io.run_one_for(deadline - now);
  }
  return true;
}

void LcmLoop::Stop() { impl_->io.stop(); }

int64_t LcmLoop::HandlePending(int64_t max_messages) {
  int64_t handled = 0;
  while (handled < max_messages && lcm_handle_timeout(impl_->lcm, 0) > 0) ++handled;
  return handled;
}

const LcmLoopStats& LcmLoop::stats() const { return impl_->stats; }

void LcmLoop::RefreshKernelDrops() { impl_->stats.kernel_drops = ReadOwnUdpDrops(); }

int64_t ReadOwnUdpDrops() {
  std::set<std::string> inodes;
  std::error_code error;
  for (const auto& entry : std::filesystem::directory_iterator("/proc/self/fd", error)) {
    std::error_code link_error;
    const std::string target = std::filesystem::read_symlink(entry.path(), link_error).string();
    // "socket:[12345]"
    if (!link_error && target.rfind("socket:[", 0) == 0 && target.back() == ']') {
      inodes.insert(target.substr(8, target.size() - 9));
    }
  }
  if (error) return -1;
  int64_t drops = 0;
  bool read_any = false;
  for (const char* table : {"/proc/net/udp", "/proc/net/udp6"}) {
    std::ifstream file(table);
    if (!file) continue;
    read_any = true;
    std::string line;
    std::getline(file, line);  // header
    while (std::getline(file, line)) {
      // sl local rem st tx:rx tr:when retrnsmt uid timeout inode ref pointer drops
      std::istringstream fields(line);
      std::vector<std::string> f;
      for (std::string field; fields >> field;) f.push_back(field);
      if (f.size() < 13 || inodes.count(f[9]) == 0) continue;
      drops += std::strtoll(f[12].c_str(), nullptr, 10);
    }
  }
  return read_any ? drops : -1;
}

}  // namespace anchormap
