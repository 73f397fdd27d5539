#include "common/bus/authenticator.h"

#include <openssl/crypto.h>
#include <openssl/evp.h>
#include <openssl/hmac.h>

#include <algorithm>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "anchormap/signed_t.hpp"
#include "common/bus/codec_internal.h"
#include "common/bus/lcm_log.h"
#include "common/bus/wire_check.h"

namespace anchormap {
namespace {

constexpr char kDomain[] = "anchormap.signed_t/1";
constexpr size_t kMaxIdLength = 64;
constexpr int32_t kMaxPayload = 1 << 30;

int HexValue(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

void AppendLength(std::vector<uint8_t>* out, size_t n) {
  for (int shift = 24; shift >= 0; shift -= 8) out->push_back(static_cast<uint8_t>(n >> shift));
}

void AppendField(std::vector<uint8_t>* out, const uint8_t* data, size_t size) {
  AppendLength(out, size);
  out->insert(out->end(), data, data + size);
}

void AppendField(std::vector<uint8_t>* out, const std::string& text) {
  AppendField(out, reinterpret_cast<const uint8_t*>(text.data()), text.size());
}

// HMAC-SHA-256 of the length-prefixed fields (anchormap_signed_t.lcm).
std::vector<uint8_t> Tag(const std::vector<uint8_t>& key, const std::string& channel,
                         const std::string& key_id, const std::string& sender, int64_t counter,
                         const uint8_t* payload, size_t size) {
  std::vector<uint8_t> message;
  message.reserve(sizeof(kDomain) + channel.size() + key_id.size() + sender.size() + size + 32);
  AppendField(&message, std::string(kDomain));
  AppendField(&message, channel);
  AppendField(&message, key_id);
  AppendField(&message, sender);
  for (int shift = 56; shift >= 0; shift -= 8) {
    message.push_back(static_cast<uint8_t>(static_cast<uint64_t>(counter) >> shift));
  }
  AppendField(&message, payload, size);
  std::vector<uint8_t> tag(EVP_MAX_MD_SIZE);
  unsigned int tag_size = 0;
  if (HMAC(EVP_sha256(), key.data(), static_cast<int>(key.size()), message.data(), message.size(),
           tag.data(), &tag_size) == nullptr ||
      tag_size != Authenticator::kTagBytes) {
    throw std::runtime_error("HMAC-SHA-256 failed");  // OpenSSL broken: a bug, not input
  }
  tag.resize(tag_size);
  return tag;
}

}  // namespace

Result<KeyRing> ParseKeyRing(const std::string& text) {
  KeyRing ring;
  std::istringstream lines(text);
  int number = 0;
  for (std::string line; std::getline(lines, line);) {
    ++number;
    const std::string where = "key file line " + std::to_string(number) + ": ";
    if (const size_t hash = line.find('#'); hash != std::string::npos) line.resize(hash);
    std::istringstream fields(line);
    std::string id, hex, extra;
    if (!(fields >> id)) continue;
    if (!(fields >> hex) || (fields >> extra)) {
      return Status::Error(where + "expected '<key_id> <hex secret>'");
    }
    if (id.size() > kMaxIdLength) return Status::Error(where + "key id longer than 64");
    if (Status p = codec_internal::CheckName(id, "key id"); !p.ok()) {
      return Status::Error(where + p.message());
    }
    if (hex.size() % 2 != 0 || hex.size() < 2 * Authenticator::kMinKeyBytes) {
      return Status::Error(where + "the secret must be at least " +
                           std::to_string(Authenticator::kMinKeyBytes) +
                           " bytes as an even number of hex digits");
    }
    std::vector<uint8_t> secret;
    for (size_t i = 0; i < hex.size(); i += 2) {
      const int hi = HexValue(hex[i]), lo = HexValue(hex[i + 1]);
      if (hi < 0 || lo < 0) return Status::Error(where + "the secret is not hex");
      secret.push_back(static_cast<uint8_t>(16 * hi + lo));
    }
    if (!ring.keys.emplace(id, std::move(secret)).second) {
      return Status::Error(where + "key id '" + id + "' appears twice");
    }
    if (ring.first_id.empty()) ring.first_id = id;
  }
  if (ring.keys.empty()) return Status::Error("the key file holds no key");
  return ring;
}

Result<KeyRing> LoadKeyFile(const std::string& path) {
  std::ifstream file(path);
  if (!file) return Status::Error(ErrorCode::kIoError, "cannot read key file '" + path + "'");
  std::ostringstream text;
  text << file.rdbuf();
  Result<KeyRing> ring = ParseKeyRing(text.str());
  if (!ring.ok()) return Status::Error(ring.status().code(), path + ": " + ring.status().message());
  return ring;
}

Result<Authenticator> LoadAuthenticator(const std::string& key_file, AuthenticatorOptions options) {
  Result<KeyRing> keys = LoadKeyFile(key_file);
  if (!keys.ok()) return keys.status();
  return Authenticator::Create(std::move(*keys), std::move(options));
}

Status OpenLoggedEvent(Authenticator* authenticator, LogEvent* event) {
  if (!authenticator) return Status::Ok();
  Result<std::vector<uint8_t>> payload =
      authenticator->Open(event->channel, event->data.data(), event->data.size());
  if (!payload.ok()) return payload.status();
  event->data = std::move(*payload);
  return Status::Ok();
}

Result<Authenticator> Authenticator::Create(KeyRing keys, AuthenticatorOptions options) {
  if (options.signing_key_id.empty()) options.signing_key_id = keys.first_id;
  if (keys.keys.count(options.signing_key_id) == 0) {
    return Status::Error("signing key '" + options.signing_key_id + "' is not in the key file");
  }
  if (Status p = codec_internal::CheckName(options.sender, "sender"); !p.ok()) return p;
  if (options.sender.size() > kMaxIdLength) return Status::Error("sender longer than 64");
  if (options.first_counter < 0) return Status::Error("first counter must be >= 0");
  if (options.replay_window < 1) return Status::Error("replay window must be >= 1");
  if (options.max_senders < 1) return Status::Error("max senders must be >= 1");
  return Authenticator(std::move(keys), std::move(options));
}

std::vector<uint8_t> Authenticator::Seal(const std::string& channel, const uint8_t* payload,
                                         size_t size) {
  anchormap::signed_t envelope;
  envelope.key_id = options_.signing_key_id;
  envelope.sender = options_.sender;
  envelope.counter = next_counter_++;
  envelope.payload_size = static_cast<int32_t>(size);
  envelope.payload.assign(payload, payload + size);
  const std::vector<uint8_t> tag = Tag(keys_.keys.at(envelope.key_id), channel, envelope.key_id,
                                       envelope.sender, envelope.counter, payload, size);
  std::copy(tag.begin(), tag.end(), envelope.tag);
  return codec_internal::Encode(envelope);
}

Result<std::vector<uint8_t>> Authenticator::Open(const std::string& channel, const uint8_t* data,
                                                 size_t size) {
  uint64_t hash = 0;
  WireCursor cursor(data, size);
  if (!cursor.ReadUint64(&hash) || hash != static_cast<uint64_t>(anchormap::signed_t::getHash())) {
    return Status::Error(ErrorCode::kUnsigned, "not an anchormap.signed_t envelope");
  }
  anchormap::signed_t envelope;
  if (Status p = codec_internal::SafeDecode(data, size, CheckSignedWire, &envelope); !p.ok()) {
    return p;
  }
  const auto key = keys_.keys.find(envelope.key_id);
  if (key == keys_.keys.end()) {
    return Status::Error(ErrorCode::kUnknownKey, "key id '" + envelope.key_id + "'");
  }
  const std::vector<uint8_t> expected =
      Tag(key->second, channel, envelope.key_id, envelope.sender, envelope.counter,
          envelope.payload.data(), envelope.payload.size());
  if (CRYPTO_memcmp(expected.data(), envelope.tag, kTagBytes) != 0) {
    return Status::Error(ErrorCode::kBadTag, "tag does not match (key '" + envelope.key_id +
                                                 "', sender '" + envelope.sender + "')");
  }
  // Authentic from here: the sender and counter are the key holder's.
  if (envelope.counter < 0) {
    return Status::Error(ErrorCode::kReplay, "negative counter");
  }
  const auto id = std::make_pair(envelope.key_id, envelope.sender);
  auto window = windows_.find(id);
  const size_t ring = static_cast<size_t>(options_.replay_window);
  if (window == windows_.end()) {
    if (windows_.size() >= options_.max_senders) {
      return Status::Error(ErrorCode::kCapReached,
                           "more than " + std::to_string(options_.max_senders) + " senders");
    }
    Window fresh;
    fresh.highest = envelope.counter;
    fresh.seen.assign(ring, false);
    fresh.seen[static_cast<size_t>(envelope.counter) % ring] = true;
    windows_.emplace(id, std::move(fresh));
    return std::move(envelope.payload);
  }
  Window& w = window->second;
  const int64_t counter = envelope.counter;
  if (counter > w.highest) {
    const uint64_t ahead = static_cast<uint64_t>(counter - w.highest);
    if (ahead >= ring) {
      std::fill(w.seen.begin(), w.seen.end(), false);
    } else {
      for (int64_t c = w.highest + 1; c < counter; ++c)
        w.seen[static_cast<size_t>(c) % ring] = false;
    }
    w.highest = counter;
    w.seen[static_cast<size_t>(counter) % ring] = true;
    return std::move(envelope.payload);
  }
  if (static_cast<uint64_t>(w.highest - counter) >= ring) {
    return Status::Error(ErrorCode::kReplay, "counter " + std::to_string(counter) +
                                                 " is older than the replay window of " +
                                                 envelope.sender);
  }
  const size_t slot = static_cast<size_t>(counter) % ring;
  if (w.seen[slot]) {
    return Status::Error(ErrorCode::kReplay, "counter " + std::to_string(counter) + " of " +
                                                 envelope.sender + " again");
  }
  w.seen[slot] = true;
  return std::move(envelope.payload);
}

Status CheckSignedWire(const void* data, size_t size) {
  WireCursor c(data, size);
  if (Status p = CheckFingerprint<anchormap::signed_t>(&c); !p.ok()) return p;
  if (Status p = c.SkipString("key_id", kMaxIdLength); !p.ok()) return p;
  if (Status p = c.SkipString("sender", kMaxIdLength); !p.ok()) return p;
  if (Status p = c.SkipField(8, "counter"); !p.ok()) return p;
  int32_t n = 0;
  if (Status p = c.ReadCount("payload_size", kMaxPayload, 1, &n); !p.ok()) return p;
  return c.SkipField(static_cast<size_t>(n) + Authenticator::kTagBytes, "payload/tag");
}

}  // namespace anchormap
