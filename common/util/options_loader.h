#pragma once
// Maps a config file and command-line flags onto plain options structs (one source of defaults per
// option).
//
// Each option is registered once, with a pointer to its struct field, a dotted config key
// ("keyframer.max_distance_m"), a flag ("--keyframe-distance-m") and a help text. The
// field's current value is the default. From that one list come: flag parsing, the config
// file (Boost.Program_options' INI format: `key = value`, or `[section]` then
// `name = value`, '#' comments), `--help`, the effective configuration printed at start-up
// and the markdown table in docs/. Precedence: defaults < config file < flags.
// Unknown flags or keys, malformed values and positional arguments are refused with the
// offending name (exit status 2, the convention for usage errors).

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "common/util/status.h"

namespace anchormap {

// What the caller should do after Parse().
struct ParseOutcome {
  bool run = true;    // false: exit now with exit_code (after --help, or an error)
  int exit_code = 0;  // 0 after --help / --print-config, 2 for usage errors
  Status error;       // the usage error, if any (already printed to stderr by Parse)
};

class OptionsLoader {
 public:
  // `usage` is the first help line after the program name, e.g. "--robot R1 [options]".
  OptionsLoader(std::string program, std::string usage, std::string description);

  // Registers a field. `flag` is the command-line name without dashes; empty derives it
  // from the key (dots and underscores become dashes). `required` options have no
  // default: the run fails with exit 2 when neither the file nor a flag sets them.
  void Add(const std::string& key, const std::string& flag, double* field, const std::string& help,
           bool required = false);
  void Add(const std::string& key, const std::string& flag, int* field, const std::string& help,
           bool required = false);
  void Add(const std::string& key, const std::string& flag, int64_t* field, const std::string& help,
           bool required = false);
  void Add(const std::string& key, const std::string& flag, bool* field, const std::string& help,
           bool required = false);
  void Add(const std::string& key, const std::string& flag, std::string* field,
           const std::string& help, bool required = false);

  // Parses flags (and the file named by --config). Prints --help / --print-config output
  // to stdout and errors to stderr.
  ParseOutcome Parse(int argc, const char* const argv[]);

  // The common tail of a daemon's start: checks the log level, sets it and the log
  // component, and logs the effective configuration under `heading`.
  Status StartLogging(const std::string& log_level, const std::string& component,
                      const std::string& heading = "effective configuration") const;
  // Prints "<program>: <message>" and a pointer to --help to stderr; returns exit code 2.
  int UsageError(const Status& problem) const;

  std::string HelpText() const;
  // "key = value" lines in registration order: the effective configuration.
  std::string EffectiveConfig() const;
  // A markdown table (flag, config key, default, meaning) for the README.
  std::string MarkdownTable() const;
  // True when the flag or config key was given explicitly in the last Parse().
  bool WasSet(const std::string& key) const;

 private:
  struct Entry {
    std::string key;
    std::string flag;
    std::string type;  // "number", "integer", "bool", "text"
    std::string help;
    std::string default_text;
    bool required = false;
    bool set = false;
    std::function<std::string()> get;
    // Parses text into the field.
    std::function<Status(const std::string&)> assign;
  };
  void AddEntry(Entry entry);

  std::string program_;
  std::string usage_;
  std::string description_;
  std::vector<Entry> entries_;
};

// A double as the loader prints it ("%.10g").
std::string FormatDouble(double value);

}  // namespace anchormap
