// Compiled only into fw_core_portable (with -fno-exceptions -fno-rtti): puts
// every header-only part of the core through the compiler with the flags a
// microcontroller build uses. Never linked into a program.
#include <cstdint>

#include "core/FieldSet.hpp"
#include "core/LatestValueRegister.hpp"
#include "core/MessageBoard.hpp"
#include "core/MessageBoardUser.hpp"
#include "core/SampleBuffer.hpp"
#include "core/Scheduler.hpp"
#include "core/StartupStatus.hpp"

namespace core {

template class LatestValueRegister<std::uint16_t>;
template class LatestValueRegister<std::int16_t>;
template class LatestValueRegister<float>;
template class SampleBuffer<std::int16_t, 16>;
template class SampleBuffer<float, 64>;

}  // namespace core
