// The 0x100A string (manufacturer software version) of this executable. It lives in a section
// of its own (HIL_SOFTWARE_VERSION_SECTION, board/cia302.hpp), cia302::kImageVersionBytes long
// and NUL-padded, holding board.toml's software_version at build time; `python -m boardproto
// image --version V` stamps another one into a copy of the executable (objcopy
// --update-section). That is how the same build becomes a second image that answers 0x100A
// with another version.
#pragma once

#include <string_view>

namespace linuxhw {

// The stamped version; board.toml's when nothing else was stamped.
std::string_view software_version();

}  // namespace linuxhw
