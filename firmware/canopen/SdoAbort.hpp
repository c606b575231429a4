// SDO abort codes (CiA 301, 7.2.4.3.17) in the engine's namespace. The codes and their texts are
// generated from protocol/boardproto/cia301.py into board/cia301.hpp (cia301::SdoAbort,
// cia301::kSdoAborts); this header only names them for namespace co.
#pragma once

#include "board/cia301.hpp"

namespace co {

using SdoAbort = cia301::SdoAbort;
using cia301::to_code;

}  // namespace co
