// The firmware's command line: its options and their parser. Board-independent (what differs per
// board comes in CommandLineText), so it is compiled once per build tree and not in each board's
// main.cpp: CLI11 is header-only and its parser is the most expensive code of the firmware to
// compile (most of main.cpp's compile time, which ran once per board).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace linuxhw {

enum class Mode { Lockstep, Free };

// What the command line sets; the caller's values are the defaults --help shows.
struct Options {
  std::string can_interface = "vcan0";
  int node_id = 0;  // the board's default node id, set by the caller
  Mode mode = Mode::Lockstep;
  std::uint32_t period_us = 0;  // the board's default period, set by the caller
  std::string params_file;
  bool print_schedule = false;
  std::uint32_t rogue_write_cycle = 0;  // test-only fault injection; 0 = off
  bool acceptance_filter = true;
  std::optional<std::uint32_t> serial_number;  // 0x1018:4; unset: derived by the caller
  std::string lss_store;  // LSS store configuration's file (node id, bit timing)
  std::string chain_in;   // emulated chain enable input: high while this file exists
  std::string chain_out;  // emulated chain enable output: this file exists while we have an id
  std::string image_dir;  // CiA 302-3 program download: staged and running images
};

// The board's part of the command line's text and checks.
struct CommandLineText {
  std::string_view program;            // the executable's name, in --help and in errors
  std::string_view board_description;  // first words of --help
  std::uint8_t unconfigured_node_id;   // CiA 305's "no node id yet" (LSS only), accepted by --node-id
  std::string rogue_write_help;        // --inject-rogue-write-at-cycle's help (names the board's field)
  std::uint32_t period_us_min;         // the periods --period-us accepts (the board's table)
  std::uint32_t period_us_max;
};

// Exit code of a bad command line.
inline constexpr int kExitUsage = 2;

// Parses argv into `options`. An exit code when the program is to stop now (0 after --help,
// kExitUsage after a one-line error on stderr); nothing when it is to run.
std::optional<int> parse_command_line(int argc, char** argv, const CommandLineText& text, Options& options);

}  // namespace linuxhw
