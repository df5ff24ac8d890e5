#pragma once
/// @file
/// How much memory the machine can give a new volume or message, so that a file or a sender
/// that declares more is refused before anything is read or allocated (a small compressed file
/// can declare gigabytes of voxels; a 58-byte OpenIGTLink header can declare a 1 GiB body).

#include <cstdint>
#include <optional>
#include <string>

namespace vh::io {

/// Memory kept free when checking a declared size (the program, the GUI, VTK's copies) [bytes].
inline constexpr std::uint64_t kMemoryMargin_bytes = std::uint64_t{256} << 20;

/// MemAvailable of /proc/meminfo (the kernel's estimate of memory available to new allocations
/// without swapping) [bytes]; none where it cannot be read (not Linux).
std::optional<std::uint64_t> availableMemoryBytes();

/// "1.5 GiB", "300 MiB", "12 KiB", "17 bytes".
std::string formatBytes(std::uint64_t bytes);

/// Whether `bytes` more fit: `bytes` + kMemoryMargin_bytes <= MemAvailable (true when unknown).
bool fitsInMemory(std::uint64_t bytes);

/// @throws std::runtime_error "<what> declares 6.0 GiB but 3.1 GiB of memory is available (256 MiB
///         kept free)" when !fitsInMemory(bytes).
void requireFitsInMemory(std::uint64_t bytes, const std::string& what);

}  // namespace vh::io
