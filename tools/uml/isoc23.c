/* The C23 spellings of strtol and strtoul, which glibc 2.38 added and Debian 12's glibc (2.36)
 * lacks: Debian's newer user-mode-linux binary asks for them and for nothing else of 2.38
 * (tools/uml-kernel links this in). C23 adds "0b" binary prefixes to them; the kernel parses
 * its command line and /proc numbers in decimal and hex only. */
#include <stdlib.h>

long __isoc23_strtol(const char *text, char **end, int base);
unsigned long __isoc23_strtoul(const char *text, char **end, int base);

long __isoc23_strtol(const char *text, char **end, int base) { return strtol(text, end, base); }

unsigned long __isoc23_strtoul(const char *text, char **end, int base) {
  return strtoul(text, end, base);
}
