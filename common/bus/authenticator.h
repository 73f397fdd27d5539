#pragma once
// The authentication layer the daemons apply to bytes (docs/ARCHITECTURE.md, "Forged
// input"): Seal wraps an encoded message in an anchormap.signed_t envelope whose tag is an
// HMAC-SHA-256 (OpenSSL) over the channel, key id, sender, a per-sender counter and the
// payload; Open checks an envelope and returns the payload, or why not (kUnsigned,
// kUnknownKey, kBadTag, kReplay, kCapReached), for the caller's RejectCounter. No LCM loop
// here, no clock: the caller gives the first counter (wall-clock microseconds at start,
// so that a restarted sender never reuses a counter).
//
// Key file (text, one key a line, '#' starts a comment):
//     <key_id> <secret as hex, at least 32 bytes = 64 hex digits>
// A fleet shares one line; with keys per robot the server's file holds every robot's key
// and each agent's file its own (plus the others' to check their relayed encounters).

#include <cstddef>
#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "common/util/status.h"

namespace anchormap {

struct KeyRing {
  std::map<std::string, std::vector<uint8_t>> keys;  // key id -> secret
  std::string first_id;                              // the file's first key
};

// Parses key file text (format above); refuses short secrets, bad hex, duplicate ids.
Result<KeyRing> ParseKeyRing(const std::string& text);
Result<KeyRing> LoadKeyFile(const std::string& path);

struct AuthenticatorOptions {
  std::string signing_key_id;  // empty: the key file's first key
  std::string sender;          // this daemon's name in its envelopes (e.g. "R1", "server")
  int64_t first_counter = 1;   // the first envelope's counter (wall-clock microseconds)
  // Counters up to this far below a sender's highest are accepted once each (reordering).
  int replay_window = 1024;
  size_t max_senders = 4096;  // (key id, sender) pairs remembered; a new one past this is refused
};

class Authenticator {
 public:
  static constexpr size_t kTagBytes = 32;
  static constexpr size_t kMinKeyBytes = 32;

  static Result<Authenticator> Create(KeyRing keys, AuthenticatorOptions options);

  // The envelope of `payload` for `channel`, under the signing key with the next counter.
  std::vector<uint8_t> Seal(const std::string& channel, const uint8_t* payload, size_t size);
  // The payload of an envelope received on `channel`, or why it is refused. A refused
  // envelope does not change the replay state.
  Result<std::vector<uint8_t>> Open(const std::string& channel, const uint8_t* data, size_t size);

  const std::string& signing_key_id() const { return options_.signing_key_id; }
  size_t senders() const { return windows_.size(); }

 private:
  struct Window {
    int64_t highest = 0;
    std::vector<bool> seen;  // seen[i]: counter highest - i arrived (ring of replay_window)
  };
  Authenticator(KeyRing keys, AuthenticatorOptions options)
      : keys_(std::move(keys)),
        options_(std::move(options)),
        next_counter_(options_.first_counter) {}

  KeyRing keys_;
  AuthenticatorOptions options_;
  int64_t next_counter_;
  std::map<std::pair<std::string, std::string>, Window> windows_;
};

// The --key-file help of the offline tools that read the server's outputs (eval, render).
inline constexpr char kServerOutputKeyFileHelp[] =
    "accept only the server's outputs signed with a key of this file (the server's --key-file; "
    "empty: unsigned outputs)";

// LoadKeyFile and Create in one step: what every main with --key-file does (the daemons
// that sign, and the viewer and the offline tools, which only check).
Result<Authenticator> LoadAuthenticator(const std::string& key_file, AuthenticatorOptions options);

// Opens `event` in place when `authenticator` is set: its data becomes the envelope's
// payload; the refusal (unsigned, bad tag, ...) otherwise. Without one the event stays as
// it is. For the tools that read a logged bus.
struct LogEvent;
Status OpenLoggedEvent(Authenticator* authenticator, LogEvent* event);

// The pre-flight size check of an anchormap.signed_t (for fuzzing and tests).
Status CheckSignedWire(const void* data, size_t size);

}  // namespace anchormap
