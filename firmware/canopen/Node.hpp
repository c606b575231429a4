// The CANopen (CiA 301) slave engine: NMT slave, heartbeat producer and consumer, SYNC consumer,
// SDO server, RPDOs/TPDOs with run-time mapping, EMCY producer, store/restore of parameters.
//
// Hardware-agnostic and single-threaded: the caller feeds received frames to process(), calls
// poll() often (timers), and after each SYNC runs one control cycle and calls
// transmit_synchronous_pdos(). Time enters only as `now_us` (a free-running microsecond clock
// that may wrap) and, for a lockstep heartbeat consumer, advance_control_time(), so tests drive
// it. All state is fixed-size; no heap, exceptions or RTTI.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>

#include "CanPort.hpp"
#include "Emcy.hpp"
#include "HeartbeatConsumer.hpp"
#include "Interfaces.hpp"
#include "LssSlave.hpp"
#include "ParameterImage.hpp"
#include "ProgramDownload.hpp"
#include "Recorder.hpp"
#include "SdoAbort.hpp"
#include "SdoServer.hpp"
#include "board/cia301.hpp"
#include "board/fields.hpp"

namespace co {

// Values are the heartbeat state bytes (CiA 301, 7.2.8.3.2.2); Initialising is the state
// before start() and the boot-up message's byte. Generated from boardproto.cia301.
using NmtState = cia301::NmtState;
// NMT command specifiers (CiA 301, 7.2.8.3.1), generated from boardproto.cia301.
using NmtCommand = cia301::NmtCommand;

// What process() saw that the caller must act on.
struct ProcessResult {
  bool sync = false;              // a SYNC arrived: run one control cycle, then call
                                  // transmit_synchronous_pdos()
  bool boot_sync = false;         // a SYNC while the node boots (booting()), under
                                  // TimeoutClock::ControlCycles: call advance_control_time()
                                  // (the boot time's clock) and run no control cycle (the
                                  // application does not run while the node boots)
  bool sync_has_counter = false;  // the SYNC carried a counter byte
  std::uint8_t sync_counter = 0;  // that byte (1..240), 0 without one
  bool application_reset = false; // NMT reset node: bus-owned fields are back at their
                                  // power-on values; reset component state if needed
};

// What 0x1010 "store parameters" / 0x1011 "restore default parameters" act on: the value is the
// sub-index (CiA 301, 7.5.2.13/14).
enum class ParameterGroup : std::uint8_t {
  All = 1,            // everything below
  Communication = 2,  // 0x1005, 0x1016, 0x1017, 0x1019, 0x1020, PDO communication and mapping
  Application = 3,    // board fields marked `stored` in board.toml
};

// Called on NMT reset node, before the node sets the application's objects to their power-on
// values: the platform resets its components, the board and its driver registers.
class ApplicationReset {
 public:
  virtual ~ApplicationReset() = default;
  virtual void reset_application() = 0;

 protected:
  ApplicationReset() = default;
  ApplicationReset(const ApplicationReset&) = default;
  ApplicationReset& operator=(const ApplicationReset&) = default;
};

enum class ParameterLoad : std::uint8_t {
  NotAttempted,   // start() not called yet
  Loaded,         // a valid image was applied
  NothingStored,  // storage empty: defaults stay
  Rejected,       // image corrupt (magic/version/size/CRC): defaults stay
};

// Diagnostics; all counts since construction (wrap at 2^32).
struct NodeCounters {
  std::uint32_t frames_received = 0;      // every frame given to process()
  std::uint32_t frames_ignored = 0;       // not for this node, or not served in this state
  std::uint32_t frames_malformed = 0;     // wrong length for NMT/SYNC/SDO, unknown NMT command
  std::uint32_t nmt_commands = 0;         // NMT commands addressed to this node (or broadcast)
  std::uint32_t syncs_received = 0;
  std::uint32_t sdo_requests = 0;
  std::uint32_t sdo_aborts_sent = 0;
  std::uint32_t rpdos_received = 0;       // applied or buffered until the next SYNC
  std::uint32_t rpdo_length_errors = 0;   // shorter than the mapping: dropped, EMCY pdo_length_error
  std::uint32_t rpdo_values_rejected = 0; // mapped value out of range or refused by the board
  std::uint32_t tpdos_sent = 0;
  std::uint32_t heartbeats_sent = 0;
  std::uint32_t heartbeats_consumed = 0;  // heartbeats (and boot-ups) of nodes 0x1016 watches
  std::uint32_t heartbeat_events = 0;     // a watched heartbeat timed out (0x1016)
  std::uint32_t emcy_sent = 0;            // includes error reset messages
  std::uint32_t send_failures = 0;        // port refused a frame (queue full / error): dropped,
                                          // except a block-upload segment, offered again later
  std::uint32_t field_writes_refused = 0; // FieldAccess::write refused (SDO, RPDO, defaults)
  std::uint32_t default_pdo_errors = 0;   // default PDO mappings the OD could not resolve
  std::uint32_t lss_requests = 0;         // LSS frames (cia305::kMasterCobId) served or not
};

// The clock of the node's timeouts on its peers: the heartbeat consumer's (0x1016) and the SDO
// server's (a client silent mid-transfer). The choice is the platform's: the node cannot tell
// whether its SYNCs are real time or simulation time. The event-driven TPDOs' inhibit time and
// event timer run on it too: in lockstep a change goes out in the cycle that made it, and the
// next one after as many cycles as the inhibit time spans, whatever the host's speed. The
// heartbeat producer always runs on now_us (a master's heartbeat consumer judges it on its own
// clock).
enum class TimeoutClock : std::uint8_t {
  WallTime,       // the now_us of process() and poll(): a board that keeps its own period
  ControlCycles,  // only advance_control_time() moves it, by the control period per cycle: in
                  // lockstep every SYNC is one period of simulation time, so a slow or paused
                  // host never trips it and a rig can predict the trip cycle exactly
};

class Node final {
 public:
  static constexpr std::size_t kErrorHistoryDepth = board::kErrorHistoryLength;  // 0x1003 subs
  static constexpr std::size_t kMaxActiveErrors = 8;
  static constexpr std::size_t kMaxMappedObjects = 8;
  static constexpr std::uint32_t kStoreSignature = 0x6576'6173;    // "save", LE
  static constexpr std::uint32_t kRestoreSignature = 0x6461'6F6C;  // "load", LE
  // Block-upload segments sent per process() or poll() call at most; the rest of a sub-block
  // follows at the next poll. About what a 1 Mbit/s bus carries in the 1 ms between two polls
  // (8-byte frames take 111..135 us), and below SocketCAN's default transmit queue of 10
  // frames: a 127-segment sub-block neither holds up the control loop nor overflows the driver.
  static constexpr std::size_t kSdoSegmentsPerCall = 8;
  // accepted_ids() at most: NMT, SYNC, the SDO request, every RPDO, every 0x1016 entry, LSS.
  static constexpr std::size_t kMaxAcceptedIds = 4 + board::kRpdoCount + board::kHeartbeatConsumers;

  // `node_id` 1..127, or cia305::kNodeIdUnconfigured (0xFF): no node id yet, LSS only until a
  // master configures one (CiA 305). A node id stored by LSS (set_lss_storage) replaces it at
  // start(). All references must outlive the node; it owns none of them. Nothing is sent or
  // written before start().
  Node(std::uint8_t node_id, CanPort& port, FieldAccess& fields, HilIo& hil,
       ParameterStorage& storage, std::uint32_t serial_number = 0);
  Node(const Node&) = delete;
  Node& operator=(const Node&) = delete;

  // Initialising -> applies stored parameters -> boot-up message -> pre-operational. Without a
  // node id the node stays initialising and serves LSS only: no boot-up, no NMT, no heartbeat,
  // until LSS gives it one (then it resets communication and sends its boot-up).
  void start(std::uint32_t now_us);

  // How long after NMT reset node / reset communication the boot-up goes out (board.toml's
  // [node] boot_ms unless set; 0: from inside the process() that got the command). Meanwhile
  // the node is initialising: it has reset what the command resets, and answers nothing, sends
  // nothing (no heartbeat, EMCY, SDO or PDO) and ignores every frame but LSS and, under
  // TimeoutClock::ControlCycles, the SYNC that clocks it (ProcessResult::boot_sync). The time is the timeout clock's:
  // simulation time in lockstep (advance_control_time(), so the boot-up comes in the same cycle
  // whatever the host's speed), the now_us of poll() otherwise. start() (power-on) and LSS
  // giving the node its id send the boot-up at once.
  void set_boot_time_us(std::uint32_t boot_time_us) { boot_time_us_ = boot_time_us; }
  std::uint32_t boot_time_us() const { return boot_time_us_; }
  // True from an NMT reset until its boot-up went out.
  bool booting() const { return booting_; }

  // Where LSS store configuration keeps the node id and bit timing (a storage of its own, apart
  // from 0x1010's). Set before start(); without it LSS answers "storing not supported".
  void set_lss_storage(ParameterStorage* storage) { lss_.set_storage(storage); }
  // The chain enable input of LssSlave (high by default): while low, LSS requests are ignored.
  void set_lss_enabled(bool enabled) { lss_.set_enabled(enabled); }
  const LssSlave& lss() const { return lss_; }
  // True once started with a node id (the chain enable output of LssSlave's doc).
  bool has_node_id() const { return started_ && cia301::is_node_id(node_id_); }

  // One received frame. Never blocks; answers (SDO, ...) are sent from inside.
  ProcessResult process(const CanFrame& frame, std::uint32_t now_us);

  // The 11-bit COB-IDs process() acts on in the present configuration, ascending, each once:
  // NMT, SYNC (0x1005), the SDO request, every valid RPDO (0x1400+n:01), the heartbeat of every
  // node a used 0x1016 entry watches. Any other frame, and every remote or 29-bit one, process()
  // only counts as ignored. The set follows the configuration, not the NMT state: an NMT
  // command takes effect at once and the frames after it must not wait for a filter. Returns
  // how many ids `out` holds.
  std::size_t accepted_ids(std::span<std::uint32_t, kMaxAcceptedIds> out) const;

  // Told the accepted set at start() and whenever it changes (0x1005, 0x1016 or an RPDO COB-ID
  // written, reset communication / node reloading stored values), from inside the call that
  // changed it and before the answer goes out (see AcceptanceListener). Optional; must outlive
  // the node. Set after start(), it hears the present set at once.
  void set_acceptance_listener(AcceptanceListener* listener);

  // Timers: heartbeat producer (and, on TimeoutClock::WallTime, consumer and SDO server timeout),
  // event-driven TPDOs (event timer, change of value limited by the inhibit time), RPDO
  // deadlines (EMCY rpdo_timeout); and the next segments of an SDO block upload. Call at least
  // once per millisecond for exact timing.
  void poll(std::uint32_t now_us);

  // Microseconds from `now_us` until the next of poll()'s timers is due (0 if one is; at most
  // `limit_us`): the heartbeat producer, the wall-clock consumer and SDO timeouts, an
  // event-driven TPDO's event timer or the end of its inhibit time, an RPDO deadline. A loop that
  // also wakes for every received frame (process(), then poll()) may sleep this long instead of
  // polling every millisecond: in lockstep an idle node then wakes only for its heartbeat.
  std::uint32_t us_until_next_timer(std::uint32_t now_us, std::uint32_t limit_us) const;

  // True while block-upload segments wait to be sent and the transmit queue took the last one:
  // the caller polls again at once instead of sleeping (8 segments a millisecond would cap a
  // 64 KiB upload at 56 kB/s). False after a refused send, so a full queue is not spun on.
  bool sdo_segments_due() const { return sdo_.segments_due() && !segment_send_refused_; }

  // Sends the synchronous TPDOs due at the last SYNC (type n: every n-th SYNC; type 0: when
  // the mapped values changed). Call once per SYNC, after the control cycle.
  void transmit_synchronous_pdos(std::uint32_t now_us);

  // The clock of the heartbeat consumer and the SDO server timeout (default WallTime). With
  // ControlCycles, call advance_control_time(period) once per control cycle, before running it:
  // a heartbeat that timed out then reaches the application in that same cycle, and a transfer
  // whose client fell silent is aborted there.
  void set_timeout_clock(TimeoutClock clock) { timeout_clock_ = clock; }
  void advance_control_time(std::uint32_t elapsed_us);

  // EMCY producer. An error stays active until cleared; reporting an active error again (same
  // code and manufacturer bytes) sends nothing and returns false. Otherwise: error register
  // updated, 0x1003 history pushed, frame sent (pre-operational/operational only), true.
  bool report_emcy(const EmcyReport& report);
  bool report_emcy(std::uint16_t error_code, std::uint8_t error_register_bits,
                   const EmcyManufacturerBytes& manufacturer);
  // Clears one active error (code and manufacturer bytes) or all with `error_code`, and sends
  // an error reset (code 0x0000, the remaining error register). false: nothing was active.
  bool clear_emcy(const EmcyReport& report);
  bool clear_emcy(std::uint16_t error_code);
  bool clear_all_emcy();

  // Local equivalents of writing 0x1010 / 0x1011 sub `group`. false: storage or the board
  // refused. Store keeps the stored values of the other group. Restore: application defaults
  // apply at once and are stored; communication defaults are dropped from storage and apply at
  // the next reset communication (CiA 301: restored values are valid after a reset).
  bool store_parameters(ParameterGroup group = ParameterGroup::All);
  bool restore_default_parameters(ParameterGroup group = ParameterGroup::All);

  // Optional: without it, reset node resets only what the node holds (bus-written fields and
  // the HIL inputs' read-back). Must outlive the node.
  void set_application_reset(ApplicationReset* reset) { application_reset_ = reset; }

  // The field recorder whose objects (board.toml's [recorder]) the node serves; the platform
  // owns it (static memory) and feeds it a sample after every control cycle. Without one those
  // objects do not exist. Reset node resets it. Must outlive the node.
  void set_recorder(Recorder* recorder) { recorder_ = recorder; }

  // Told whenever the heartbeat consumer's state changes (a heartbeat event, a heartbeat back,
  // 0x1016 rewritten, a reset). Optional; must outlive the node. A heartbeat event also reports
  // EMCY heartbeat_error naming the lost node; the node never clears it itself: whoever acts on
  // the event (the application's fault latch) clears it. The NMT state then follows 0x1029:01
  // (error behaviour; default: operational enters pre-operational).
  void set_heartbeat_listener(HeartbeatListener* listener) { heartbeat_listener_ = listener; }

  // CiA 302-3 program download (0x1F50, 0x1F51, 0x1F56, 0x1F57) into `store`; without one
  // a download is refused (0x08000020, flash status "flash secured"). Must outlive the node.
  void set_program_store(ProgramStore* store) { program_.set_store(store); }
  const ProgramDownload& program() const { return program_; }
  // 0x1F51 Start arrived with a complete, checked image staged, and its answer has been sent:
  // the platform now runs that image (on Linux: re-executes the process from it).
  bool program_start_requested() const { return program_.start_requested(); }

  // 0x100A (manufacturer software version); board.toml's unless the platform knows better
  // (the Linux target reads the version stamped into its executable). `version` must outlive
  // the node.
  void set_software_version(std::string_view version) { software_version_ = version; }

  NmtState state() const { return state_; }
  std::uint8_t node_id() const { return node_id_; }
  std::uint8_t error_register() const { return error_register_; }
  ParameterLoad parameter_load() const { return parameter_load_; }
  const NodeCounters& counters() const { return counters_; }
  std::uint16_t heartbeat_period_ms() const { return heartbeat_ms_; }
  std::uint8_t lost_heartbeats() const { return heartbeat_consumer_.lost_entries(); }

 private:
  // FieldArrayCount: sub 0 of an ARRAY of board fields, its value (the member count) in `id`.
  enum class Target : std::uint8_t { Communication, Field, HilInput, HilOutput, Recorder, Program, FieldArrayCount };
  // One (index, sub-index) of the object dictionary as the SDO server and PDOs see it.
  struct Entry {
    board::DataType type = board::DataType::Unsigned32;
    std::uint8_t size = 0;  // bytes (0: a string or DOMAIN, sized by its value)
    bool readable = true;
    bool writable = false;
    Target target = Target::Communication;
    std::uint8_t id = 0;  // FieldId / HilInputId / HilOutputId as a number
  };
  struct MappedObject {
    Target target = Target::Field;
    std::uint8_t id = 0;
    std::uint8_t size = 0;  // bytes
    board::DataType type = board::DataType::Real32;
  };
  struct Pdo {
    // Communication parameter (0x1400+n / 0x1800+n).
    std::uint32_t cob_id = 0x8000'0000u;  // bit 31 set: not valid
    std::uint8_t transmission_type = 255;
    std::uint16_t inhibit_time_100us = 0;  // TPDO only
    std::uint16_t event_timer_ms = 0;      // TPDO only
    std::uint8_t sync_start_value = 0;     // TPDO only (sub 6); 0 = not used
    // Mapping parameter (0x1600+n / 0x1A00+n).
    std::uint8_t mapping_count = 0;
    std::array<std::uint32_t, kMaxMappedObjects> mapping{};
    std::array<MappedObject, kMaxMappedObjects> mapped{};  // resolved mapping[0..count)
    std::uint8_t payload_bytes = 0;
    // Run-time state.
    std::uint8_t syncs_since_sent = 0;
    bool due_at_sync = false;
    bool sync_started = false;  // the SYNC start value was seen (or is not used)
    bool sent_once = false;
    bool change_held = false;  // event-driven: a change waits for the inhibit time to end
    std::uint32_t last_sent_us = 0;
    std::array<std::uint8_t, 8> last_payload{};
    bool buffered = false;  // synchronous RPDO waiting for the next SYNC
    bool received_once = false;  // RPDO deadline monitoring
    bool deadline_missed = false;
    std::uint32_t last_received_us = 0;
    std::array<std::uint8_t, 8> buffer{};

    bool valid() const { return (cob_id & 0x8000'0000u) == 0; }
    std::uint32_t can_id() const { return cob_id & cia301::kStandardIdMask; }
  };
  struct ActiveError {
    EmcyReport report;
    bool active = false;
  };

  // The SDO server's view of the object dictionary (ObjectDictionary.cpp).
  static ObjectAccess object_access(Node& node);
  // Object dictionary access by (index, sub-index) (ObjectDictionary.cpp).
  SdoAbort check_writable(std::uint16_t index, std::uint8_t sub, std::size_t& size);
  SdoAbort read(std::uint16_t index, std::uint8_t sub, std::span<std::uint8_t> out,
                std::size_t& length);
  SdoAbort read_at(std::uint16_t index, std::uint8_t sub, std::size_t offset,
                   std::span<std::uint8_t> out, std::size_t& length, std::size_t& total_size);
  SdoAbort write(std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> data,
                 std::uint32_t now_us);

  // Object dictionary (ObjectDictionary.cpp).
  SdoAbort find_entry(std::uint16_t index, std::uint8_t sub, Entry& entry) const;
  std::string_view string_value(std::uint16_t index) const;
  std::uint32_t read_communication(std::uint16_t index, std::uint8_t sub) const;
  SdoAbort write_communication(std::uint16_t index, std::uint8_t sub, std::uint32_t value,
                               std::uint32_t now_us);
  SdoAbort write_field(board::FieldId id, float value);
  SdoAbort write_program_control(std::uint32_t value);
  SdoAbort write_hil_input(board::HilInputId id, std::uint32_t raw);
  std::int32_t hil_input_value(board::HilInputId id) const;

  // PDOs (Pdo.cpp).
  SdoAbort write_pdo_communication(Pdo& pdo, bool is_rpdo, std::uint8_t sub, std::uint32_t value);
  SdoAbort write_pdo_mapping(Pdo& pdo, bool is_rpdo, std::uint8_t sub, std::uint32_t value);
  SdoAbort resolve_mapping(std::uint32_t entry, bool is_rpdo, MappedObject& mapped) const;
  void load_default_pdos();
  void load_default_pdo(Pdo& pdo, const board::PdoDefault& defaults, bool is_rpdo);
  void reset_pdo_runtime();
  void receive_rpdo(std::size_t number, const CanFrame& frame, std::uint32_t now_us);
  void poll_rpdo_deadlines(std::uint32_t now_us);
  void apply_rpdo(const Pdo& pdo, std::span<const std::uint8_t> data);
  std::uint8_t build_tpdo(const Pdo& pdo, std::array<std::uint8_t, 8>& data);
  void send_tpdo(Pdo& pdo, const std::array<std::uint8_t, 8>& data, std::uint8_t len,
                 std::uint32_t now_us);
  void poll_event_tpdos(std::uint32_t now_us);
  std::uint32_t us_until_pdo_timer(std::uint32_t now_us, std::uint32_t limit_us) const;

  // NMT, storage, EMCY (Node.cpp).
  void handle_nmt(const CanFrame& frame, std::uint32_t now_us, ProcessResult& result);
  void handle_sync(const CanFrame& frame, ProcessResult& result);
  bool handle_heartbeat(const CanFrame& frame, std::uint32_t now_us);
  std::uint32_t timeout_now(std::uint32_t now_us) const;
  void check_heartbeat_timeouts(std::uint32_t consumer_now_us);
  void check_sdo_timeout(std::uint32_t server_now_us);
  void tell_heartbeat_listener(bool event);
  void handle_sdo(const CanFrame& frame, std::uint32_t now_us);
  void handle_lss(const CanFrame& frame, std::uint32_t now_us);
  void tell_acceptance_listener();
  void send_sdo_segments(std::uint32_t now_us);
  bool segment_send_refused_ = false;  // the last segment the port was given, it refused
  void enter(NmtState state);
  void reset_communication(std::uint32_t now_us, bool boot_at_once = true);
  void check_boot(std::uint32_t clock_now_us, std::uint32_t now_us);
  void send_boot_up(std::uint32_t now_us);
  void apply_power_on_values();
  ParameterLoad load_stored_parameters();
  void load_stored_communication();
  bool load_stored_pdo(Pdo& pdo, bool is_rpdo, std::uint16_t communication_index,
                       std::uint16_t mapping_index, std::span<const std::byte> image,
                       std::size_t count);
  std::size_t collect_communication(std::span<parameter_image::StoredValue> out) const;
  std::size_t collect_application(std::span<parameter_image::StoredValue> out);
  std::size_t stored_entries(std::span<parameter_image::StoredValue> out, bool communication);
  bool save_image(std::span<const parameter_image::StoredValue> values, std::size_t count);
  void send_emcy(std::uint16_t code, const EmcyManufacturerBytes& manufacturer);
  void update_error_register();
  bool may_send_emcy() const;
  bool send(std::uint32_t id, std::span<const std::uint8_t> data);

  std::uint8_t node_id_;
  CanPort& port_;
  FieldAccess& fields_;
  HilIo& hil_;
  ParameterStorage& storage_;
  std::uint32_t serial_number_;
  SdoServer sdo_;
  LssSlave lss_;
  bool started_ = false;

  NmtState state_ = NmtState::Initialising;
  std::uint32_t sync_cob_id_ = cia301::kSyncCobId;
  std::uint8_t sync_overflow_ = 0;  // 0x1019: 0 = SYNC without counter, else counter 1..value
  std::uint32_t configuration_date_ = 0;  // 0x1020:01, days since 1984-01-01 (written by a master)
  std::uint32_t configuration_time_ = 0;  // 0x1020:02, ms after midnight
  std::uint16_t heartbeat_ms_ = 0;
  std::uint32_t last_heartbeat_us_ = 0;
  HeartbeatConsumer heartbeat_consumer_;
  // 0x1029:01: what a heartbeat event does to the NMT state (CiA 301 default: pre-operational).
  cia301::ErrorBehaviour communication_error_ = cia301::ErrorBehaviour::PreOperational;
  TimeoutClock timeout_clock_ = TimeoutClock::WallTime;
  std::uint32_t boot_time_us_ = board::kNode.boot_ms * 1000u;
  bool booting_ = false;             // an NMT reset's boot-up not sent yet
  std::uint32_t boot_started_us_ = 0;  // on the timeout clock
  std::uint32_t last_now_us_ = 0;    // the latest now_us given: the wall time of a boot-up that
                                     // advance_control_time() ends
  std::uint32_t control_time_us_ = 0;  // TimeoutClock::ControlCycles; wraps
  std::uint8_t told_lost_heartbeats_ = 0;  // what the listener last heard
  HeartbeatListener* heartbeat_listener_ = nullptr;
  AcceptanceListener* acceptance_listener_ = nullptr;
  std::array<std::uint32_t, kMaxAcceptedIds> told_accepted_ids_{};  // what the listener last heard
  std::size_t told_accepted_count_ = 0;  // 0: nothing told yet (the set always holds NMT)
  std::array<Pdo, board::kRpdoCount> rpdos_{};
  std::array<Pdo, board::kTpdoCount> tpdos_{};
  std::array<std::int32_t, board::kHilInputCount> hil_inputs_{};  // last values written

  std::uint8_t error_register_ = 0;
  std::array<ActiveError, kMaxActiveErrors> active_errors_{};
  std::array<std::uint32_t, kErrorHistoryDepth> error_history_{};  // [0] = newest
  std::uint8_t error_history_count_ = 0;

  ParameterLoad parameter_load_ = ParameterLoad::NotAttempted;
  ApplicationReset* application_reset_ = nullptr;
  Recorder* recorder_ = nullptr;
  ProgramDownload program_{board::kNode.product_code};
  std::string_view software_version_ = board::kNode.software_version;
  std::array<std::byte, parameter_image::kCapacity> image_{};
  std::array<parameter_image::StoredValue, parameter_image::kMaxEntries> staged_{};
  NodeCounters counters_;
};

}  // namespace co
