# CMake toolchain of the microcontroller build (`make cortex-m`, build/cortex-m): Debian's Arm
# bare-metal GCC (gcc-arm-none-eabi) with newlib, for a Cortex-M4F (Armv7E-M, single-precision
# FPU, hard-float calling convention). The host build (build/) never sees this file.
set(CMAKE_SYSTEM_NAME Generic)
set(CMAKE_SYSTEM_PROCESSOR arm)

set(CMAKE_C_COMPILER arm-none-eabi-gcc)
set(CMAKE_CXX_COMPILER arm-none-eabi-g++)
set(CMAKE_ASM_COMPILER arm-none-eabi-gcc)
set(CMAKE_OBJCOPY arm-none-eabi-objcopy CACHE FILEPATH "")
set(CMAKE_SIZE arm-none-eabi-size CACHE FILEPATH "")

# No program links without a linker script and start-up code (firmware/platform/cortex-m), so
# CMake's compiler checks build a static library instead.
set(CMAKE_TRY_COMPILE_TARGET_TYPE STATIC_LIBRARY)

set(HIL_CORTEX_M_CPU_FLAGS -mcpu=cortex-m4 -mthumb -mfloat-abi=hard -mfpu=fpv4-sp-d16)
# Everything this tree compiles is built as firmware is: no exceptions, no RTTI, each function
# and object in its own section so the linker drops what nothing uses.
string(JOIN " " _hil_cortex_m_flags ${HIL_CORTEX_M_CPU_FLAGS}
       -ffunction-sections -fdata-sections -fno-exceptions -fno-rtti -fno-threadsafe-statics)
set(CMAKE_CXX_FLAGS_INIT "${_hil_cortex_m_flags}")
string(JOIN " " _hil_cortex_m_c_flags ${HIL_CORTEX_M_CPU_FLAGS} -ffunction-sections -fdata-sections)
set(CMAKE_C_FLAGS_INIT "${_hil_cortex_m_c_flags}")
string(JOIN " " _hil_cortex_m_link ${HIL_CORTEX_M_CPU_FLAGS} -Wl,--gc-sections)
set(CMAKE_EXE_LINKER_FLAGS_INIT "${_hil_cortex_m_link}")

# Libraries and headers come from the cross toolchain only, programs (the protocol generator's
# Python) from the host.
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)
