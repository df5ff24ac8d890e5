#pragma once
/// @file
/// What the two recording readers (recording.cpp's .vhrec, recording_hdf5.cpp's HDF5) check alike.

#include <cstddef>
#include <string>
#include <string_view>

#include "vh/runtime/recording.h"

namespace vh::runtime {

/// The deepest nesting of arrays and objects in JSON text `text` (brackets inside strings not
/// counted); O(n), no parse. Any text: what is not JSON gives some depth, and the parse says the rest.
std::size_t jsonNestingDepth(std::string_view text) noexcept;

/// @throws std::runtime_error "<where>damaged metadata: JSON nested N deep (at most M)" when
///         `metadata_json` nests deeper than kMaxRecordingJsonDepth.
void requireMetadataDepth(const std::string& where, const std::string& metadata_json);

/// Drops the events whose detail nests deeper than kMaxRecordingJsonDepth, with one warning
/// ("WHERE: N event(s) dropped: ...") when any was.
void dropTooDeepEvents(const std::string& where, Recording& rec);

}  // namespace vh::runtime
