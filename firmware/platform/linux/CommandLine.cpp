// The firmware's command line (CommandLine.hpp): CLI11, once per build tree.
#include "CommandLine.hpp"

#include <CLI/CLI.hpp>
#include <cstdio>
#include <cstdlib>

namespace linuxhw {

std::optional<int> parse_command_line(int argc, char** argv, const CommandLineText& text, Options& options) {
  CLI::App app{
      std::string(text.board_description) +
      ", a CANopen (CiA 301) node on SocketCAN.\n"
      "In lockstep mode every SYNC from the bus runs exactly one control cycle and the\n"
      "synchronous TPDOs answer it (the rig drives simulation time). In free mode the\n"
      "firmware keeps its own period with an absolute-deadline timer, as on a real board.",
      std::string(text.program)};
  app.add_option("--can", options.can_interface, "SocketCAN interface")->capture_default_str();
  app.add_option("--node-id", options.node_id,
                 "CANopen node id (1..127), or 0xFF: none yet, LSS only (CiA 305) until a master\n"
                 "configures one; an id stored by LSS (--lss-store) wins over this one")
      ->check(CLI::Validator(
          [&text](std::string& given) -> std::string {
            char* end = nullptr;
            const long value = std::strtol(given.c_str(), &end, 0);
            const bool ok = end != given.c_str() && *end == '\0' &&
                            ((value >= 1 && value <= 127) || value == text.unconfigured_node_id);
            return ok ? std::string{} : "node id " + given + " is not 1..127 or 0xFF";
          },
          "1..127|0xFF"))
      ->capture_default_str();
  app.add_option("--serial", options.serial_number,
                 "serial number (0x1018:4), the part of the LSS address that tells boards of one\n"
                 "product apart (fastscan finds them by it). Default: a CRC-32 of /etc/machine-id\n"
                 "and the absolute path of --lss-store (else --params), stable across restarts")
      ->envname("HIL_SERIAL");
  app.add_option("--lss-store", options.lss_store,
                 "file for LSS store configuration (node id, bit timing); loaded at start-up");
  app.add_option("--chain-in", options.chain_in,
                 "emulated chain enable input of a modular robot: LSS is served only while this\n"
                 "file exists (the upstream module's --chain-out). Default: always enabled");
  app.add_option("--chain-out", options.chain_out,
                 "emulated chain enable output: this file exists while the node has a node id");
  app.add_option("--image-dir", options.image_dir,
                 "directory of program download (CiA 302-3, 0x1F50..0x1F57): a downloaded image is\n"
                 "staged there and, on 0x1F51 start, run from there (the process re-executes\n"
                 "itself with the same arguments). Without it a download is refused (flash secured)")
      ->check(CLI::ExistingDirectory);
  std::string mode = "lockstep";
  app.add_option("--mode", mode, "lockstep: one cycle per SYNC; free: own timer")
      ->check(CLI::IsMember({"lockstep", "free"}))
      ->capture_default_str();
  app.add_option("--period-us", options.period_us,
                 "control cycle period in microseconds (the cycle time the components use)")
      ->check(CLI::Range(text.period_us_min, text.period_us_max))
      ->capture_default_str();
  app.add_option("--params", options.params_file,
                 "file for stored parameters (0x1010 store / 0x1011 restore); loaded at start-up");
  app.add_flag("--print-schedule", options.print_schedule,
               "print the control cycle's update order with each component's reads and writes, and exit");
  bool accept_all = false;
  app.add_flag("--no-acceptance-filter", accept_all,
               "receive every frame on the bus. By default the socket's kernel filter\n"
               "(CAN_RAW_FILTER) passes only the COB-IDs the node consumes (NMT, SYNC, its SDO\n"
               "requests, its valid RPDOs, the heartbeats 0x1016 watches), as a CAN controller's\n"
               "hardware filter would: with N modules on one bus, a frame then wakes only the\n"
               "firmware that uses it. This option is for debugging (see every frame arrive)\n"
               "and for tests that count how the node ignores frames not meant for it");
  app.add_option("--inject-rogue-write-at-cycle", options.rogue_write_cycle, text.rogue_write_help)
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp&) {
    std::fputs(app.help().c_str(), stdout);
    return 0;
  } catch (const CLI::ParseError& error) {
    const int name_length = static_cast<int>(text.program.size());
    std::fprintf(stderr, "%.*s: %s (see %.*s --help)\n", name_length, text.program.data(), error.what(), name_length,
                 text.program.data());
    return kExitUsage;
  }
  options.mode = mode == "free" ? Mode::Free : Mode::Lockstep;
  options.acceptance_filter = !accept_all;
  return std::nullopt;
}

}  // namespace linuxhw
