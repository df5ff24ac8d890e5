/// @file
/// The tick columns' one table (tick_columns.h).

#include "vh/runtime/tick_columns.h"

#include <array>
#include <cstddef>

#include "vh/runtime/tick_record.h"

namespace vh::runtime {
namespace {

constexpr std::size_t at(std::size_t base, std::size_t i) { return base + i * sizeof(double); }

constexpr std::array<TickColumn, 30> kColumns = {{
      {"t_s", "s", "servo time since the recording started", offsetof(TickRecord, time_s), TickColumn::kF64},
      {"tick", "1", "servo tick counter", offsetof(TickRecord, tick), TickColumn::kU64},
      {"device_x_m", "m", "device position in W, x", at(offsetof(TickRecord, p_WD_m), 0), TickColumn::kF64},
      {"device_y_m", "m", "device position in W, y", at(offsetof(TickRecord, p_WD_m), 1), TickColumn::kF64},
      {"device_z_m", "m", "device position in W, z", at(offsetof(TickRecord, p_WD_m), 2), TickColumn::kF64},
      {"device_qw", "1", "device orientation in W, quaternion w", at(offsetof(TickRecord, q_WD), 0), TickColumn::kF64},
      {"device_qx", "1", "device orientation in W, quaternion x", at(offsetof(TickRecord, q_WD), 1), TickColumn::kF64},
      {"device_qy", "1", "device orientation in W, quaternion y", at(offsetof(TickRecord, q_WD), 2), TickColumn::kF64},
      {"device_qz", "1", "device orientation in W, quaternion z", at(offsetof(TickRecord, q_WD), 3), TickColumn::kF64},
      {"proxy_x_m", "m", "proxy position in W, x", at(offsetof(TickRecord, p_WP_m), 0), TickColumn::kF64},
      {"proxy_y_m", "m", "proxy position in W, y", at(offsetof(TickRecord, p_WP_m), 1), TickColumn::kF64},
      {"proxy_z_m", "m", "proxy position in W, z", at(offsetof(TickRecord, p_WP_m), 2), TickColumn::kF64},
      {"proxy_qw", "1", "proxy orientation in W, quaternion w", at(offsetof(TickRecord, q_WP), 0), TickColumn::kF64},
      {"proxy_qx", "1", "proxy orientation in W, quaternion x", at(offsetof(TickRecord, q_WP), 1), TickColumn::kF64},
      {"proxy_qy", "1", "proxy orientation in W, quaternion y", at(offsetof(TickRecord, q_WP), 2), TickColumn::kF64},
      {"proxy_qz", "1", "proxy orientation in W, quaternion z", at(offsetof(TickRecord, q_WP), 3), TickColumn::kF64},
      {"force_x_N", "N", "force on the hand in W, x", at(offsetof(TickRecord, force_W_N), 0), TickColumn::kF64},
      {"force_y_N", "N", "force on the hand in W, y", at(offsetof(TickRecord, force_W_N), 1), TickColumn::kF64},
      {"force_z_N", "N", "force on the hand in W, z", at(offsetof(TickRecord, force_W_N), 2), TickColumn::kF64},
      {"torque_x_Nm", "N*m", "torque on the hand in W, x", at(offsetof(TickRecord, torque_W_Nm), 0), TickColumn::kF64},
      {"torque_y_Nm", "N*m", "torque on the hand in W, y", at(offsetof(TickRecord, torque_W_Nm), 1), TickColumn::kF64},
      {"torque_z_Nm", "N*m", "torque on the hand in W, z", at(offsetof(TickRecord, torque_W_Nm), 2), TickColumn::kF64},
      {"contacts", "1", "contact set size", offsetof(TickRecord, contacts), TickColumn::kU32},
      {"isovalue", "data units", "isovalue (HU for CT)", offsetof(TickRecord, isovalue), TickColumn::kF64},
      {"tick_time_s", "s", "the solver's compute time of the tick", offsetof(TickRecord, tick_time_s), TickColumn::kF64},
      {"flags", "1", "kRecordFlag* bits (tick_record.h); bits 16..31: touched segment + 1",
       offsetof(TickRecord, flags), TickColumn::kU32},
      {"critical_distance_m", "m", "point shell to the nearest critical segment (inf: none within range, nan: "
       "not measured)", offsetof(TickRecord, critical_distance_m), TickColumn::kF64},
      {"critical_segment", "1", "that segment's index (-1: none)", offsetof(TickRecord, critical_segment),
       TickColumn::kI32},
      {"removed_voxels", "1", "voxels the burr removed on the tick", offsetof(TickRecord, removed_voxels),
       TickColumn::kU32},
      {"deadline_work", "1", "1 + the work at which the solver's deadline cut the tick (0: not cut)",
       offsetof(TickRecord, deadline_work), TickColumn::kI64},
}};


static_assert(sizeof(double) == 8);
static_assert(
    [] {
      for (const TickColumn& c : kColumns)
        if (c.offset + tickColumnBytes(c.kind) > sizeof(TickRecord)) return false;
      return true;
    }(),
    "a tick column lies outside TickRecord");

}  // namespace

std::span<const TickColumn> tickColumns() noexcept { return kColumns; }

}  // namespace vh::runtime
