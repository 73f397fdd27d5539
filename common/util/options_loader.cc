#include "common/util/options_loader.h"

#include <cerrno>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <sstream>
#include <utility>

#include <boost/program_options.hpp>

#include "common/util/log.h"
#include "common/util/text_fields.h"

namespace anchormap {
namespace po = boost::program_options;

namespace {

bool ParseBool(const std::string& text, bool* value) {
  if (text == "true" || text == "1" || text == "yes" || text == "on") {
    *value = true;
  } else if (text == "false" || text == "0" || text == "no" || text == "off") {
    *value = false;
  } else {
    return false;
  }
  return true;
}

}  // namespace

std::string FormatDouble(double value) {
  char text[40];
  std::snprintf(text, sizeof(text), "%.10g", value);
  return text;
}

OptionsLoader::OptionsLoader(std::string program, std::string usage, std::string description)
    : program_(std::move(program)),
      usage_(std::move(usage)),
      description_(std::move(description)) {}

void OptionsLoader::AddEntry(Entry entry) {
  if (entry.flag.empty()) {
    entry.flag = entry.key;
    for (char& c : entry.flag) {
      if (c == '.' || c == '_') c = '-';
    }
  }
  entry.default_text = entry.get();
  entries_.push_back(std::move(entry));
}

void OptionsLoader::Add(const std::string& key, const std::string& flag, double* field,
                        const std::string& help, bool required) {
  AddEntry({key, flag, "number", help, "", required, false,
            [field] { return FormatDouble(*field); },
            [field](const std::string& text) {
              return ParseFiniteDouble(text, field)
                         ? Status::Ok()
                         : Status::Error("'" + text + "' is not a finite number");
            }});
}

void OptionsLoader::Add(const std::string& key, const std::string& flag, int64_t* field,
                        const std::string& help, bool required) {
  AddEntry({key, flag, "integer", help, "", required, false,
            [field] { return std::to_string(*field); },
            [field](const std::string& text) {
              return ParseInt64(text, field) ? Status::Ok()
                                             : Status::Error("'" + text + "' is not an integer");
            }});
}

void OptionsLoader::Add(const std::string& key, const std::string& flag, int* field,
                        const std::string& help, bool required) {
  AddEntry({key, flag, "integer", help, "", required, false,
            [field] { return std::to_string(*field); },
            [field](const std::string& text) {
              int64_t value = 0;
              if (!ParseInt64(text, &value) || value < INT_MIN || value > INT_MAX) {
                return Status::Error("'" + text + "' is not a 32-bit integer");
              }
              *field = static_cast<int>(value);
              return Status::Ok();
            }});
}

void OptionsLoader::Add(const std::string& key, const std::string& flag, bool* field,
                        const std::string& help, bool required) {
  AddEntry({key, flag, "bool", help, "", required, false,
            [field] { return std::string(*field ? "true" : "false"); },
            [field](const std::string& text) {
              return ParseBool(text, field) ? Status::Ok()
                                            : Status::Error("'" + text + "' is not true/false");
            }});
}

void OptionsLoader::Add(const std::string& key, const std::string& flag, std::string* field,
                        const std::string& help, bool required) {
  AddEntry({key, flag, "text", help, "", required, false, [field] { return *field; },
            [field](const std::string& text) {
              *field = text;
              return Status::Ok();
            }});
}

ParseOutcome OptionsLoader::Parse(int argc, const char* const argv[]) {
  ParseOutcome outcome;
  auto fail = [&](const std::string& message) {
    outcome.run = false;
    outcome.exit_code = 2;
    outcome.error = Status::Error(message);
    std::cerr << program_ << ": " << message << "\n(see " << program_ << " --help)\n";
    return outcome;
  };

  po::options_description flags;
  flags.add_options()("help,h", "")("print-config", "")("print-options-markdown", "")(
      "config", po::value<std::string>());
  po::options_description file_keys;
  for (const Entry& e : entries_) {
    auto* value = po::value<std::string>();
    if (e.type == "bool") value->implicit_value("true");
    flags.add_options()(e.flag.c_str(), value);
    file_keys.add_options()(e.key.c_str(), po::value<std::string>());
  }

  po::variables_map from_flags;
  try {
    const po::positional_options_description no_positionals;
    po::store(po::command_line_parser(argc, argv).options(flags).positional(no_positionals).run(),
              from_flags);
  } catch (const po::error& error) {
    return fail(error.what());
  }
  if (from_flags.count("help")) {
    std::cout << HelpText();
    outcome.run = false;
    return outcome;
  }
  if (from_flags.count("print-options-markdown")) {
    std::cout << MarkdownTable();
    outcome.run = false;
    return outcome;
  }

  po::variables_map from_file;
  if (from_flags.count("config")) {
    const std::string path = from_flags["config"].as<std::string>();
    std::ifstream file(path);
    if (!file) return fail("cannot read config file '" + path + "'");
    try {
      po::store(po::parse_config_file(file, file_keys, /*allow_unregistered=*/false), from_file);
    } catch (const po::unknown_option& error) {
      return fail("config file '" + path + "': unknown key '" + error.get_option_name() + "'");
    } catch (const po::error& error) {
      return fail("config file '" + path + "': " + error.what());
    }
  }

  for (Entry& e : entries_) {
    e.set = false;
    if (from_file.count(e.key)) {
      const Status assigned = e.assign(from_file[e.key].as<std::string>());
      if (!assigned.ok()) return fail("config key '" + e.key + "': " + assigned.message());
      e.set = true;
    }
    if (from_flags.count(e.flag)) {
      const Status assigned = e.assign(from_flags[e.flag].as<std::string>());
      if (!assigned.ok()) return fail("--" + e.flag + ": " + assigned.message());
      e.set = true;
    }
    if (e.required && !e.set) {
      return fail("--" + e.flag + " (config key '" + e.key + "') is required");
    }
  }

  if (from_flags.count("print-config")) {
    std::cout << EffectiveConfig();
    outcome.run = false;
  }
  return outcome;
}

Status OptionsLoader::StartLogging(const std::string& log_level, const std::string& component,
                                   const std::string& heading) const {
  LogLevel level = LogLevel::kInfo;
  if (!ParseLogLevel(log_level, &level)) {
    return Status::Error("--log-level: '" + log_level + "' is not debug, info, warning or error");
  }
  SetMinLogLevel(level);
  SetLogComponent(component);
  std::istringstream config(EffectiveConfig());
  LogInfo(heading + ":");
  for (std::string line; std::getline(config, line);) LogInfo("  " + line);
  return Status::Ok();
}

int OptionsLoader::UsageError(const Status& problem) const {
  std::cerr << program_ << ": " << problem.message() << "\n(see " << program_ << " --help)\n";
  return 2;
}

std::string OptionsLoader::HelpText() const {
  std::ostringstream out;
  out << "Usage: " << program_ << " " << usage_ << "\n" << description_ << "\n\nOptions:\n";
  out << "  -h, --help                 this text\n"
      << "  --config FILE              read options from FILE (`key = value` lines with the\n"
      << "                             dotted keys below, or `[section]` + `name = value`);\n"
      << "                             flags override the file\n"
      << "  --print-config             print the effective configuration and exit\n"
      << "  --print-options-markdown   print the option table in markdown and exit\n";
  for (const Entry& e : entries_) {
    out << "  --" << e.flag << " <" << e.type << ">";
    if (e.required) {
      out << " (required)";
    } else {
      out << " (default: " << (e.default_text.empty() ? "\"\"" : e.default_text) << ")";
    }
    out << "\n      " << e.help << " [config key: " << e.key << "]\n";
  }
  return out.str();
}

std::string OptionsLoader::EffectiveConfig() const {
  std::ostringstream out;
  for (const Entry& e : entries_) out << e.key << " = " << e.get() << "\n";
  return out.str();
}

std::string OptionsLoader::MarkdownTable() const {
  std::ostringstream out;
  out << "| flag | config key | default | meaning |\n|---|---|---|---|\n";
  for (const Entry& e : entries_) {
    out << "| `--" << e.flag << "` | `" << e.key << "` | "
        << (e.required               ? std::string("(required)")
            : e.default_text.empty() ? std::string("(empty)")
                                     : "`" + e.default_text + "`")
        << " | " << e.help << " |\n";
  }
  return out.str();
}

bool OptionsLoader::WasSet(const std::string& key) const {
  for (const Entry& e : entries_) {
    if (e.key == key) return e.set;
  }
  return false;
}

}  // namespace anchormap
