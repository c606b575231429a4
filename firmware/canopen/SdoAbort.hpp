// SDO abort codes (CiA 301, 7.2.4.3.17). The enumerator values ARE the codes on the wire.
#pragma once

#include <cstdint>

namespace co {

enum class SdoAbort : std::uint32_t {
  None = 0x0000'0000,                  // not an abort: the access succeeded
  ToggleBitNotAlternated = 0x0503'0000,
  ProtocolTimedOut = 0x0504'0000,      // no next segment from the client in time
  CommandSpecifierInvalid = 0x0504'0001,  // unknown, or not what the transfer at hand expects
  InvalidBlockSize = 0x0504'0002,      // block mode: blksize 0 or above 127
  InvalidSequenceNumber = 0x0504'0003, // block mode: seqno 0 or past blksize, ackseq past what was sent
  CrcError = 0x0504'0004,              // block mode: the client's CRC does not match the data
  OutOfMemory = 0x0504'0005,           // the value is larger than the server can buffer
  UnsupportedAccess = 0x0601'0000,
  WriteOnly = 0x0601'0001,             // attempt to read a write-only object
  ReadOnly = 0x0601'0002,              // attempt to write a read-only object
  ObjectDoesNotExist = 0x0602'0000,
  ObjectCannotBeMapped = 0x0604'0041,
  PdoLengthExceeded = 0x0604'0042,     // mapped objects exceed the 64 bits of a PDO
  ParameterIncompatible = 0x0604'0043, // general parameter incompatibility (settings that do
                                       // not fit together, e.g. arming a recorder without channels)
  LengthMismatch = 0x0607'0010,
  LengthTooHigh = 0x0607'0012,
  LengthTooLow = 0x0607'0013,
  SubIndexDoesNotExist = 0x0609'0011,
  ValueRangeExceeded = 0x0609'0030,    // invalid value (also NaN, invalid COB-ID / type)
  ValueTooHigh = 0x0609'0031,
  ValueTooLow = 0x0609'0032,
  GeneralError = 0x0800'0000,
  DataCannotBeStored = 0x0800'0020,    // the board refused the write, or storage failed
  DeviceState = 0x0800'0022,           // not now: e.g. PDO mapping change while operational
};

constexpr std::uint32_t to_code(SdoAbort abort) { return static_cast<std::uint32_t>(abort); }

}  // namespace co
