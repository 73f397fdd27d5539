#include "tools/render/colors.h"

#include <algorithm>
#include <cmath>

namespace anchormap::render {
namespace {

Rgb FromHsv(double hue_deg, double saturation, double value) {
  const double c = value * saturation;
  const double h = std::fmod(hue_deg, 360.0) / 60.0;
  const double x = c * (1.0 - std::abs(std::fmod(h, 2.0) - 1.0));
  double r = 0, g = 0, b = 0;
  if (h < 1) {
    r = c;
    g = x;
  } else if (h < 2) {
    r = x;
    g = c;
  } else if (h < 3) {
    g = c;
    b = x;
  } else if (h < 4) {
    g = x;
    b = c;
  } else if (h < 5) {
    r = x;
    b = c;
  } else {
    r = c;
    b = x;
  }
  const double m = value - c;
  auto byte = [](double v) {
    return static_cast<uint8_t>(std::lround(std::clamp(v, 0.0, 1.0) * 255.0));
  };
  return {byte(r + m), byte(g + m), byte(b + m)};
}

// Splits "R12" into ("R", 12) for natural ordering; names without a number get -1.
std::pair<std::string, long> NaturalParts(const std::string& name) {
  size_t digits = name.size();
  while (digits > 0 && std::isdigit(static_cast<unsigned char>(name[digits - 1]))) --digits;
  if (digits == name.size() || name.size() - digits > 9) return {name, -1};
  return {name.substr(0, digits), std::stol(name.substr(digits))};
}

}  // namespace

Rgb TrajectoryColor(int index) {
  static const Rgb kPalette[] = {{31, 119, 180},  {255, 127, 14}, {44, 160, 44},   {214, 39, 40},
                                 {148, 103, 189}, {140, 86, 75},  {227, 119, 194}, {188, 189, 34},
                                 {23, 190, 207},  {31, 60, 110}};
  constexpr int kPaletteSize = sizeof(kPalette) / sizeof(kPalette[0]);
  if (index >= 0 && index < kPaletteSize) return kPalette[index];
  return FromHsv(index * 137.50776, 0.85, 0.55 + 0.3 * ((index / 3) % 2));
}

bool TrajectoryKey::operator<(const TrajectoryKey& other) const {
  const auto a = NaturalParts(robot);
  const auto b = NaturalParts(other.robot);
  if (a != b) return a < b;
  if (robot != other.robot) return robot < other.robot;
  return trajectory_id < other.trajectory_id;
}

ColorAssignment::ColorAssignment(std::vector<TrajectoryKey> keys) : keys_(std::move(keys)) {
  std::sort(keys_.begin(), keys_.end());
  keys_.erase(std::unique(keys_.begin(), keys_.end()), keys_.end());
}

Rgb ColorAssignment::ColorOf(const TrajectoryKey& key) const {
  const auto it = std::lower_bound(keys_.begin(), keys_.end(), key);
  if (it == keys_.end() || !(*it == key)) return {0, 0, 0};
  return TrajectoryColor(static_cast<int>(it - keys_.begin()));
}

}  // namespace anchormap::render
