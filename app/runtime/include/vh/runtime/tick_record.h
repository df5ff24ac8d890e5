#pragma once
/// @file
/// One servo tick of a session recording (recording.h): the fixed-size record whose byte image
/// the `.vhrec` file stores, and the meaning of its flag bits.

#include <cstddef>
#include <cstdint>
#include <limits>
#include <type_traits>

namespace vh::runtime {

/// TickRecord::flags bits.
inline constexpr std::uint32_t kRecordFlagContact = 1u << 0;        ///< contacts > 0.
inline constexpr std::uint32_t kRecordFlagBadSample = 1u << 1;      ///< No usable device sample.
inline constexpr std::uint32_t kRecordFlagDeadlineMiss = 1u << 2;   ///< Tick started > 1 period late.
inline constexpr std::uint32_t kRecordFlagForceZeroed = 1u << 3;    ///< The safety layer sent zero.
inline constexpr std::uint32_t kRecordFlagNonFinite = 1u << 4;      ///< The renderer computed a NaN / inf.
inline constexpr std::uint32_t kRecordFlagStopping = 1u << 5;       ///< Force ramped down by stop().
inline constexpr std::uint32_t kRecordFlagDeviceDisconnected = 1u << 6;  ///< Device::connected() was false.
/// Bits 16..31 of TickRecord::flags: the touched segment + 1 (0: none; see SegmentSet::segmentOf()).
inline constexpr int kRecordSegmentShift = 16;
/// The flag bits of a touched segment index (-1: none; indices above 65534 are not recorded).
constexpr std::uint32_t recordSegmentBits(int segment) noexcept {
  return segment >= 0 && segment < 65535 ? static_cast<std::uint32_t>(segment + 1) << kRecordSegmentShift : 0u;
}
/// The touched segment of a record's flags, or -1.
constexpr int recordSegment(std::uint32_t flags) noexcept { return static_cast<int>(flags >> kRecordSegmentShift) - 1; }
/// The safety layer changed the renderer's force or torque (clamped, ramped or gated; includes
/// kRecordFlagForceZeroed ticks): the force sent to the device was not the renderer's.
/// (HapticThread records the coupling's force for the record's own proxy and device poses and
/// takes this flag, ForceZeroed and Stopping from the coupling thread's latest command.)
inline constexpr std::uint32_t kRecordFlagForceLimited = 1u << 7;
/// The drill's burr was spinning after this tick's renderer step (drilling.h): a replay cuts
/// on exactly these ticks, so it rebuilds the drilled volume bit for bit.
inline constexpr std::uint32_t kRecordFlagDrillOn = 1u << 8;
/// The solver applied new coupling gains on this tick (a change made with
/// HapticThread::setGains(), which also records it as a "gains" event stamped with the last
/// solver tick before the change): a replay applies that event exactly here, whenever the
/// coupling thread passed it on. Recordings without any such flag (older ones) apply a "gains"
/// event on the first record after its tick.
inline constexpr std::uint32_t kRecordFlagGainsApplied = 1u << 9;
/// The solver's deadline on the clock stopped this tick's work (haptics::TickStats::deadline_cut:
/// the machine gave the solver less than its servo period); the proxy moved only as far as was
/// proven free and the sweep went on next tick. A replay has no clock and does the whole tick,
/// so from such a tick on it need not match bit for bit: replayRecording() names the first one
/// at or before a mismatch (ReplayComparison::deadline_cut_tick).
inline constexpr std::uint32_t kRecordFlagDeadlineCut = 1u << 10;
/// The tick is part of a jam (jam_detector.h: the proxy held in contact, far from a device pose
/// that is itself free, for more than kJamTicks ticks). The writer derives a "jam" event when
/// the flag turns on ({"ticks": kJamTicks + 1}, stamped with the first flagged record) and
/// "jam_cleared" when it turns off.
inline constexpr std::uint32_t kRecordFlagJam = 1u << 11;
/// A placement (Touch the Surface, Home, Reset Device: HapticThread::place()) moved the proxy
/// and the device together just before this tick: the proxy was put at the "placement" event's
/// "X_WP" (the events in order, one per flagged record) and the device sample is the placed
/// one. Not the hand's motion: the session's metrics leave the jump out, and a replay puts its
/// proxy there before this tick.
inline constexpr std::uint32_t kRecordFlagPlacement = 1u << 12;
/// Bits 13..15: the technique rules active after this tick (technique.h: TechniqueMonitor's
/// result, kTechniqueForce / kTechniqueSpeed / kTechniqueShaft shifted by this). The writer derives
/// a "technique" event ({"rule": "force"}) when a rule's bit turns on, so the servo thread never
/// formats an event.
inline constexpr int kRecordTechniqueShift = 13;
inline constexpr std::uint32_t kRecordFlagTechniqueMask = 7u << kRecordTechniqueShift;
/// The flag bits of the active rules `technique` (TechniqueRule bits).
constexpr std::uint32_t recordTechniqueBits(std::uint32_t technique) noexcept {
  return (technique << kRecordTechniqueShift) & kRecordFlagTechniqueMask;
}
/// The active technique rules of a record's flags (TechniqueRule bits).
constexpr std::uint32_t recordTechnique(std::uint32_t flags) noexcept {
  return (flags & kRecordFlagTechniqueMask) >> kRecordTechniqueShift;
}

/// One servo tick, fixed size, trivially copyable (its byte image is what the file stores).
/// Frames: W is the scene (world) frame; D the device (tool) frame; P the proxy frame.
struct TickRecord {
  double time_s = 0.0;                  ///< Servo time since the recording started [s].
  double p_WD_m[3] = {0, 0, 0};         ///< Device position in W [m].
  double q_WD[4] = {1, 0, 0, 0};        ///< Device orientation in W (w, x, y, z).
  double p_WP_m[3] = {0, 0, 0};         ///< Proxy position in W [m].
  double q_WP[4] = {1, 0, 0, 0};        ///< Proxy orientation in W (w, x, y, z).
  double force_W_N[3] = {0, 0, 0};      ///< Force on the hand in W [N].
  double torque_W_Nm[3] = {0, 0, 0};    ///< Torque on the hand in W [N*m].
  double isovalue = 0.0;                ///< Isovalue (data units, HU for CT).
  std::uint64_t tick = 0;               ///< Servo tick counter.
  double tick_time_s = 0.0;             ///< Compute time of the tick [s].
  std::uint32_t contacts = 0;           ///< Contact set size.
  std::uint32_t flags = 0;              ///< kRecordFlag* bits; bits 16..31: recordSegment().
  /// Distance from the proxy's point shell to the nearest critical segment's voxel centres
  /// after the tick [m] (critical_proximity.h): +infinity when none is within
  /// kProximityRange_m (or the scene has none); NaN when not measured (format versions 1 to 3).
  double critical_distance_m = std::numeric_limits<double>::infinity();
  std::int32_t critical_segment = -1;   ///< That segment (index into the scene's segments), or -1.
  /// Voxels the drill's burr removed whole on this tick (haptics::CutResult::voxels_removed; 0
  /// without a drill, and in format versions 1 to 4, which did not store it). Their sum over a
  /// recording is what the burr removed during it (session_metrics.h: removed_voxels).
  std::uint32_t removed_voxels = 0;
  /// The solver's deadline on the clock cut this tick at this work (haptics::TickStats::
  /// deadline_work: 1 + the work at the clock's read that found the deadline passed); 0 when it
  /// did not (or format versions 1 to 4). A replay stops the tick at the same work
  /// (HapticRenderer::cutNextTickAtWork()), so a recording made on a busy machine replays bit
  /// for bit (one solver lane; with several, the lanes' shares of the work are not repeatable).
  std::int64_t deadline_work = 0;
};
static_assert(std::is_trivially_copyable_v<TickRecord>);
static_assert(std::is_standard_layout_v<TickRecord>);
static_assert(sizeof(TickRecord) == 224, "the file format (version 5) stores 224-byte records");
/// The record of format versions 1 to 3: TickRecord up to and including flags.
inline constexpr std::size_t kTickRecordBytesV3 = 200;
static_assert(offsetof(TickRecord, critical_distance_m) == kTickRecordBytesV3);
/// The record of format version 4: TickRecord up to critical_segment and 4 reserved bytes (0).
inline constexpr std::size_t kTickRecordBytesV4 = 216;
static_assert(offsetof(TickRecord, removed_voxels) + sizeof(std::uint32_t) == kTickRecordBytesV4);

}  // namespace vh::runtime
