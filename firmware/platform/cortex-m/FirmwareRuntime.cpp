// What the C and C++ libraries expect of an operating system, for the firmware image, which has
// none and never ends: abort() and _exit() stop the firmware like a fault (a real board's
// watchdog then resets it), and static objects register no destructors (newlib's atexit list
// would be the only thing that could grow).
#include <cstdlib>

extern "C" {
[[noreturn]] void hil_fault(const char* what);

void abort() { hil_fault("abort"); }
void _exit(int) { hil_fault("main returned"); }
int __aeabi_atexit(void*, void (*)(void*), void*) { return 0; }
}
