#pragma once
// Valid encoded messages for the fuzz targets' seed corpus, and the node targets' input
// layout: byte 0 picks the channel (ChannelFor), the rest is the message.

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "common/bus/authenticator.h"

namespace anchormap::fuzz {

// Target name -> a few valid inputs.
std::map<std::string, std::vector<std::vector<uint8_t>>> SeedInputs();

// The channels of the node targets, indexed by the input's first byte (modulo the size).
const std::vector<std::string>& ServerNodeChannels();
const std::vector<std::string>& AgentNodeChannels();

// The fixed fleet key of the envelope target.
Authenticator FuzzAuthenticator(const std::string& sender);

}  // namespace anchormap::fuzz
