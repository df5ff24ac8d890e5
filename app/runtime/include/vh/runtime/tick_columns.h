#pragma once
/// @file
/// The columns of a TickRecord as the exports give them: one table, in `export --csv`'s order,
/// with each column's unit, meaning, place in the record and type. The CSV writer
/// (writeRecordingCsv()), the HDF5 writer and reader (recording_hdf5.h) and the Python module
/// (TICK_DTYPE, CSV_COLUMNS) all read this table, so a column added to TickRecord is added here
/// once.

#include <cstddef>
#include <span>

namespace vh::runtime {

/// One column of a tick record.
struct TickColumn {
  const char* name;         ///< As in the CSV header and the HDF5 dataset ("t_s", "device_x_m", ...).
  const char* unit;         ///< SI unit ("s", "m", "N", "N*m"), "1" for counts and flags, "data units".
  const char* description;  ///< What it is, in a few words (the HDF5 attribute).
  std::size_t offset;       ///< Byte offset of the value in TickRecord.
  /// Its type: a double, or an unsigned / signed integer of 32 or 64 bits.
  enum Kind { kF64, kU64, kU32, kI32, kI64 } kind;
};

/// The 30 columns in `export --csv`'s order.
std::span<const TickColumn> tickColumns() noexcept;

/// Bytes of a value of `kind` (8 or 4).
constexpr std::size_t tickColumnBytes(TickColumn::Kind kind) noexcept {
  return kind == TickColumn::kU32 || kind == TickColumn::kI32 ? 4 : 8;
}

}  // namespace vh::runtime
