// ScanEncounters::ExportState / ImportState (scan_encounter_state.h).

#include "server/scan_encounter_state.h"

#include "server/scan_encounters.h"

namespace anchormap {

ScanEncounterState ScanEncounters::ExportState() const {
  ScanEncounterState s;
  matches_.ExportState(&s);
  s.waiting.assign(waiting_.begin(), waiting_.end());
  submaps_.ExportState(&s);
  global_.ExportState(&s);
  qualifier_.ExportState(&s);
  s.now_utime = now_utime_;
  near_.ExportState(&s);
  s.stats = stats_;
  s.near_folded = near_folded_;
  return s;
}

void ScanEncounters::ImportState(const ScanEncounterState& s) {
  matches_.ImportState(s);
  waiting_.assign(s.waiting.begin(), s.waiting.end());
  submaps_.ImportState(s);
  global_.ImportState(s);
  qualifier_.ImportState(s);
  now_utime_ = s.now_utime;
  stats_ = s.stats;
  near_.ImportState(s);
  near_folded_ = s.near_folded;
  look_back_.Forget();
}

}  // namespace anchormap
