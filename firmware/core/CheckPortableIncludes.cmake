# Fails if a core source includes an operating-system header: the core must
# build for a bare-metal target, where POSIX and Linux headers do not exist.
# Usage: cmake -DFILES="a.cpp;b.hpp" -P CheckPortableIncludes.cmake
set(forbidden_pattern
    "^(unistd|pthread|fcntl|poll|signal|termios|dlfcn|syslog|sched|semaphore|spawn|netdb|ifaddrs|error)\\.h$|^(sys|linux|net|netinet|arpa|asm|bits)/")
set(violations "")
foreach(file IN LISTS FILES)
  file(STRINGS "${file}" include_lines REGEX "^[ \t]*#[ \t]*include[ \t]*[<\"]")
  foreach(line IN LISTS include_lines)
    string(REGEX REPLACE "^[ \t]*#[ \t]*include[ \t]*[<\"]([^>\"]+)[>\"].*$" "\\1" header "${line}")
    if(header MATCHES "${forbidden_pattern}")
      string(APPEND violations "\n  ${file}: #include <${header}>")
    endif()
  endforeach()
endforeach()
list(LENGTH FILES checked)
if(violations)
  message(FATAL_ERROR "the portable core includes operating-system headers:${violations}\n"
                      "Move the platform-specific code to firmware/platform/.")
endif()
message(STATUS "checked ${checked} core files: no operating-system headers")
