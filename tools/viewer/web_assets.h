#pragma once
// The viewer's web page (tools/viewer/web/), embedded into the binary at build time.

#include <map>
#include <string>
#include <string_view>

namespace anchormap::viewer {

// File name ("index.html", "viewer.js") -> its bytes.
const std::map<std::string, std::string_view>& EmbeddedFiles();

}  // namespace anchormap::viewer
