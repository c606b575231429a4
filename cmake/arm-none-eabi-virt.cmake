# CMake toolchain of the bare-metal build for qemu's 32-bit Arm `virt` machine (`make
# baremetal`, build/qemu-virt): the same Debian gcc-arm-none-eabi and newlib as the Cortex-M
# build (cmake/arm-none-eabi.cmake), for a Cortex-A15 (Armv7-A with the virtualization
# extensions, VFPv4 and NEON, hard-float calling convention; Thumb-2 code). The platform it
# builds is firmware/platform/qemu-virt.
set(CMAKE_SYSTEM_NAME Generic)
set(CMAKE_SYSTEM_PROCESSOR arm)
set(HIL_BAREMETAL_PLATFORM qemu-virt)

set(CMAKE_C_COMPILER arm-none-eabi-gcc)
set(CMAKE_CXX_COMPILER arm-none-eabi-g++)
set(CMAKE_ASM_COMPILER arm-none-eabi-gcc)
set(CMAKE_OBJCOPY arm-none-eabi-objcopy CACHE FILEPATH "")
set(CMAKE_SIZE arm-none-eabi-size CACHE FILEPATH "")

set(CMAKE_TRY_COMPILE_TARGET_TYPE STATIC_LIBRARY)

set(HIL_VIRT_CPU_FLAGS -mcpu=cortex-a15 -mthumb -mfloat-abi=hard -mfpu=neon-vfpv4)
string(JOIN " " _hil_virt_flags ${HIL_VIRT_CPU_FLAGS}
       -ffunction-sections -fdata-sections -fno-exceptions -fno-rtti -fno-threadsafe-statics)
set(CMAKE_CXX_FLAGS_INIT "${_hil_virt_flags}")
string(JOIN " " _hil_virt_c_flags ${HIL_VIRT_CPU_FLAGS} -ffunction-sections -fdata-sections)
set(CMAKE_C_FLAGS_INIT "${_hil_virt_c_flags}")
string(JOIN " " _hil_virt_link ${HIL_VIRT_CPU_FLAGS} -Wl,--gc-sections)
set(CMAKE_EXE_LINKER_FLAGS_INIT "${_hil_virt_link}")

set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)
