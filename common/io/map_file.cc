#include "common/io/map_file.h"

#include <cctype>
#include <cstdio>
#include <fstream>
#include <sstream>

namespace anchormap {
namespace {

// Next whitespace-separated header token, skipping '#' comments to the end of the line.
bool NextHeaderToken(std::istream& in, std::string* token) {
  token->clear();
  int c = in.get();
  while (c != EOF) {
    if (c == '#') {
      while (c != EOF && c != '\n') c = in.get();
    } else if (std::isspace(c)) {
      c = in.get();
    } else {
      break;
    }
  }
  while (c != EOF && !std::isspace(c) && c != '#') {
    token->push_back(static_cast<char>(c));
    c = in.get();
  }
  // The single whitespace after the last header field separates it from binary data.
  return !token->empty();
}

bool ParseInt(const std::string& text, int* value) {
  try {
    size_t used = 0;
    const long parsed = std::stol(text, &used);
    if (used != text.size() || parsed < 0 || parsed > 1000000) return false;
    *value = static_cast<int>(parsed);
    return true;
  } catch (const std::exception&) {
    return false;
  }
}

std::string Trim(const std::string& s) {
  const size_t begin = s.find_first_not_of(" \t\r\"'");
  if (begin == std::string::npos) return "";
  const size_t end = s.find_last_not_of(" \t\r\"'");
  return s.substr(begin, end - begin + 1);
}

}  // namespace

Status ReadPgm(const std::string& path, GrayImage* image) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::Error("cannot open PGM '" + path + "'");
  std::string magic, width, height, max_value;
  if (!NextHeaderToken(in, &magic) || (magic != "P5" && magic != "P2")) {
    return Status::Error("'" + path + "' is not a PGM file (magic '" + magic + "')");
  }
  GrayImage out;
  if (!NextHeaderToken(in, &width) || !NextHeaderToken(in, &height) ||
      !NextHeaderToken(in, &max_value) || !ParseInt(width, &out.width) ||
      !ParseInt(height, &out.height) || !ParseInt(max_value, &out.max_value) || out.width == 0 ||
      out.height == 0 || out.max_value == 0 || out.max_value > 65535) {
    return Status::Error("'" + path + "': bad PGM header");
  }
  const size_t count = static_cast<size_t>(out.width) * out.height;
  out.pixels.resize(count);
  if (magic == "P5") {
    const int bytes_per_pixel = out.max_value > 255 ? 2 : 1;
    std::vector<unsigned char> raw(count * bytes_per_pixel);
    in.read(reinterpret_cast<char*>(raw.data()), static_cast<std::streamsize>(raw.size()));
    if (static_cast<size_t>(in.gcount()) != raw.size()) {
      return Status::Error("'" + path + "': truncated PGM data");
    }
    for (size_t i = 0; i < count; ++i) {
      out.pixels[i] =
          bytes_per_pixel == 1 ? raw[i] : static_cast<uint16_t>(raw[2 * i] << 8 | raw[2 * i + 1]);
    }
  } else {
    for (size_t i = 0; i < count; ++i) {
      long value = 0;
      if (!(in >> value)) return Status::Error("'" + path + "': truncated PGM data");
      out.pixels[i] = static_cast<uint16_t>(value);
    }
  }
  for (uint16_t value : out.pixels) {
    if (value > out.max_value) return Status::Error("'" + path + "': pixel above max value");
  }
  *image = std::move(out);
  return Status::Ok();
}

Status WritePgm(const std::string& path, const GrayImage& image) {
  if (image.width <= 0 || image.height <= 0 || image.max_value <= 0 || image.max_value > 65535 ||
      image.pixels.size() != static_cast<size_t>(image.width) * image.height) {
    return Status::Error("WritePgm: inconsistent image");
  }
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) return Status::Error("cannot open '" + path + "' for writing");
  out << "P5\n" << image.width << " " << image.height << "\n" << image.max_value << "\n";
  std::vector<unsigned char> raw;
  raw.reserve(image.pixels.size() * 2);
  for (uint16_t value : image.pixels) {
    if (image.max_value > 255) raw.push_back(static_cast<unsigned char>(value >> 8));
    raw.push_back(static_cast<unsigned char>(value & 0xff));
  }
  out.write(reinterpret_cast<const char*>(raw.data()), static_cast<std::streamsize>(raw.size()));
  out.close();
  if (!out) return Status::Error("write to '" + path + "' failed");
  return Status::Ok();
}

Status WriteMapYaml(const std::string& path, const MapMetadata& metadata) {
  std::ofstream out(path, std::ios::trunc);
  if (!out) return Status::Error("cannot open '" + path + "' for writing");
  char buffer[512];
  std::snprintf(buffer, sizeof(buffer),
                "image: %s\nresolution: %.6f\norigin: [%.6f, %.6f, %.6f]\nnegate: %d\n"
                "occupied_thresh: %.3f\nfree_thresh: %.3f\n",
                metadata.image.c_str(), metadata.resolution_m, metadata.origin[0],
                metadata.origin[1], metadata.origin[2], metadata.negate, metadata.occupied_thresh,
                metadata.free_thresh);
  out << buffer;
  out.close();
  if (!out) return Status::Error("write to '" + path + "' failed");
  return Status::Ok();
}

Status ReadMapYaml(const std::string& path, MapMetadata* metadata) {
  std::ifstream in(path);
  if (!in) return Status::Error("cannot open map YAML '" + path + "'");
  MapMetadata out;
  bool has_image = false;
  bool has_resolution = false;
  std::string line;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    const size_t hash = line.find('#');
    if (hash != std::string::npos) line.resize(hash);
    const size_t colon = line.find(':');
    if (colon == std::string::npos) continue;
    const std::string key = Trim(line.substr(0, colon));
    std::string value = Trim(line.substr(colon + 1));
    const std::string where = path + ":" + std::to_string(line_number) + ": ";
    try {
      if (key == "image") {
        out.image = value;
        has_image = !value.empty();
      } else if (key == "resolution") {
        out.resolution_m = std::stod(value);
        has_resolution = true;
      } else if (key == "origin") {
        for (char& c : value) {
          if (c == '[' || c == ']' || c == ',') c = ' ';
        }
        std::istringstream list(value);
        if (!(list >> out.origin[0] >> out.origin[1] >> out.origin[2])) {
          return Status::Error(where + "origin must be [x, y, yaw]");
        }
      } else if (key == "negate") {
        out.negate = std::stoi(value);
      } else if (key == "occupied_thresh") {
        out.occupied_thresh = std::stod(value);
      } else if (key == "free_thresh") {
        out.free_thresh = std::stod(value);
      }
    } catch (const std::exception&) {
      return Status::Error(where + "cannot parse the value of '" + key + "'");
    }
  }
  if (!has_image || !has_resolution) {
    return Status::Error("'" + path + "' lacks 'image' or 'resolution'");
  }
  if (!(out.resolution_m > 0.0)) return Status::Error("'" + path + "': resolution must be > 0");
  *metadata = out;
  return Status::Ok();
}

uint8_t OccupancyToPgmValue(int occupancy_percent, const MapMetadata& metadata) {
  if (occupancy_percent < 0) return 205;
  if (occupancy_percent >= metadata.occupied_thresh * 100.0) return 0;
  if (occupancy_percent <= metadata.free_thresh * 100.0) return 254;
  return 205;
}

}  // namespace anchormap
