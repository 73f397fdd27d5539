#include "agent/outbox.h"

#include <algorithm>
#include <string>

namespace anchormap {
namespace {

size_t Index(StreamKind kind) { return kind == StreamKind::kKeyframes ? 0 : 1; }

}  // namespace

void Outbox::Erase(Stream* stream, Stream::iterator it) {
  if (it->second.spilled()) {
    --spilled_entries_;
  } else {
    bytes_ -= it->second.size;
    --in_memory_[Index(it->second.kind)];
  }
  stream->erase(it);
  // Everything spilled has been acknowledged: the file's space goes back.
  if (spilled_entries_ == 0 && spill_ && spill_->size() > 0) {
    if (Status cleared = spill_->Clear(); !cleared.ok()) {
      ++stats_.spill_failures;
      spill_error_ = cleared;
    }
  }
}

Status Outbox::Add(StreamKind kind, int32_t seq, std::vector<uint8_t> bytes, int64_t now_utime) {
  Stream& stream = StreamOf(kind);
  if (const auto old = stream.find(seq); old != stream.end()) Erase(&stream, old);
  Entry entry;
  entry.kind = kind;
  entry.seq = seq;
  entry.size = bytes.size();
  entry.bytes = std::move(bytes);
  entry.last_sent_utime = now_utime;
  bytes_ += entry.size;
  ++in_memory_[Index(kind)];
  stream.emplace(seq, std::move(entry));
  ++stats_.added;
  const int64_t failures_before = stats_.spill_failures;
  const int64_t dropped = EnforceMemoryBound();
  if (dropped == 0) return Status::Ok();
  stats_.dropped += dropped;
  const std::string what = std::to_string(dropped) + " unacknowledged messages dropped";
  if (stats_.spill_failures > failures_before) {
    return Status::Error(ErrorCode::kIoError,
                         "outbox spill failed (" + spill_error_.message() + "): " + what);
  }
  return Status::Error(ErrorCode::kQueueFull, "outbox over " + std::to_string(options_.max_bytes) +
                                                  " bytes in memory and " +
                                                  std::to_string(options_.max_spill_bytes) +
                                                  " spilled: " + what);
}

int64_t Outbox::EnforceMemoryBound() {
  int64_t dropped = 0;
  // The oldest keyframes go first (large, and the oldest are the least likely to be asked
  // for soon); encounters (small) only when no other keyframe is in memory. The newest
  // entry always stays in memory.
  while (static_cast<int64_t>(bytes_) > options_.max_bytes && in_memory_[0] + in_memory_[1] > 1) {
    Stream& victims = in_memory_[0] > 1 || in_memory_[1] == 0 ? keyframes_ : encounters_;
    const Stream::iterator oldest = OldestInMemory(&victims);
    if (oldest == victims.end()) break;
    if (Spill(&oldest->second)) continue;
    Erase(&victims, oldest);
    ++dropped;
  }
  return dropped;
}

Outbox::Stream::iterator Outbox::OldestInMemory(Stream* stream) {
  // Spilled entries are a prefix of the stream (the oldest go first): start after the
  // last one spilled rather than walk over them all.
  const size_t kind = stream == &keyframes_ ? 0 : 1;
  auto it = stream->upper_bound(last_spilled_seq_[kind]);
  while (it != stream->end() && it->second.spilled()) ++it;
  return it;
}

bool Outbox::Spill(Entry* entry) {
  if (options_.spill_dir.empty()) return false;
  if ((spill_ ? spill_->size() : 0) + static_cast<int64_t>(entry->size) >
      options_.max_spill_bytes) {
    return false;
  }
  if (!spill_) {
    Result<std::unique_ptr<SpillFile>> created = SpillFile::Create(options_.spill_dir);
    if (!created.ok()) {
      ++stats_.spill_failures;
      spill_error_ = created.status();
      return false;
    }
    spill_ = std::move(*created);
  }
  const Result<int64_t> offset = spill_->Append(entry->bytes);
  if (!offset.ok()) {
    ++stats_.spill_failures;
    spill_error_ = offset.status();
    return false;
  }
  entry->spill_offset = *offset;
  last_spilled_seq_[Index(entry->kind)] =
      std::max(last_spilled_seq_[Index(entry->kind)], entry->seq);
  std::vector<uint8_t>().swap(entry->bytes);  // the memory goes back now
  bytes_ -= entry->size;
  --in_memory_[Index(entry->kind)];
  ++spilled_entries_;
  ++stats_.spilled;
  return true;
}

bool Outbox::TakeForSending(Entry* entry, int64_t now_utime, std::vector<Message>* out) {
  Message message;
  message.kind = entry->kind;
  message.seq = entry->seq;
  if (entry->spilled()) {
    Result<std::vector<uint8_t>> bytes = spill_->Read(entry->spill_offset, entry->size);
    if (!bytes.ok()) {
      ++stats_.spill_failures;
      spill_error_ = bytes.status();
      return false;
    }
    message.bytes = std::move(*bytes);
    ++stats_.read_back;
  } else {
    message.bytes = entry->bytes;
  }
  entry->last_sent_utime = now_utime;
  ++entry->sends;
  out->push_back(std::move(message));
  return true;
}

std::string Outbox::Unacknowledged() const {
  const auto describe = [](const char* name, const Stream& stream) {
    if (stream.empty()) return std::string(name) + " none";
    return std::string(name) + " " + std::to_string(stream.begin()->first) + ".." +
           std::to_string(stream.rbegin()->first) + " (" + std::to_string(stream.size()) + ")";
  };
  return describe("keyframes", keyframes_) + ", " + describe("encounters", encounters_);
}

void Outbox::Acknowledge(int32_t keyframes_next, int32_t encounters_next) {
  for (auto* stream : {&keyframes_, &encounters_}) {
    const int32_t next = stream == &keyframes_ ? keyframes_next : encounters_next;
    while (!stream->empty() && stream->begin()->first < next) {
      Erase(stream, stream->begin());
      ++stats_.acknowledged;
    }
  }
}

std::vector<Outbox::Message> Outbox::EncountersLeftByAck(int64_t now_utime) {
  std::vector<Message> out;
  if (options_.encounter_resend_after_ack_s <= 0) return out;
  for (auto& [seq, entry] : encounters_) {
    if (out.size() >= static_cast<size_t>(options_.max_resend_per_poll)) break;
    if (1e-6 * static_cast<double>(now_utime - entry.last_sent_utime) <
        options_.encounter_resend_after_ack_s) {
      continue;
    }
    if (TakeForSending(&entry, now_utime, &out)) ++stats_.resent_after_ack;
  }
  return out;
}

std::vector<Outbox::Message> Outbox::Requested(const std::vector<SeqRange>& ranges,
                                               int64_t now_utime) {
  std::vector<Message> out;
  for (const SeqRange& range : ranges) {
    Stream& stream = StreamOf(range.kind);
    int64_t found = 0;
    for (auto it = stream.lower_bound(range.first); it != stream.end() && it->first <= range.last;
         ++it) {
      ++found;
      if (TakeForSending(&it->second, now_utime, &out)) ++stats_.resent_on_request;
    }
    const int64_t asked = static_cast<int64_t>(range.last) - range.first + 1;
    stats_.requested_but_gone += asked - found;
  }
  return out;
}

std::vector<Outbox::Message> Outbox::TimedOut(int64_t now_utime) {
  std::vector<Entry*> due;
  for (auto* stream : {&keyframes_, &encounters_}) {
    for (auto& [seq, entry] : *stream) {
      const double wait_s = options_.resend_timeout_s * (1 << std::min(entry.sends - 1, 2));
      if (1e-6 * static_cast<double>(now_utime - entry.last_sent_utime) >= wait_s) {
        due.push_back(&entry);
      }
    }
  }
  std::stable_sort(due.begin(), due.end(), [](const Entry* a, const Entry* b) {
    return a->last_sent_utime < b->last_sent_utime;
  });
  if (due.size() > static_cast<size_t>(options_.max_resend_per_poll)) {
    due.resize(static_cast<size_t>(options_.max_resend_per_poll));
  }
  std::vector<Message> out;
  for (Entry* entry : due) {
    if (TakeForSending(entry, now_utime, &out)) ++stats_.resent_on_timeout;
  }
  return out;
}

}  // namespace anchormap
