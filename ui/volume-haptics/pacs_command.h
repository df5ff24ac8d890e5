#pragma once
/// @file
/// `volume-haptics pacs echo|find|get`: the PACS client of vh/io/pacs.h for scripts, without a
/// window (no Qt, no display).

#include <functional>

#include <CLI/CLI.hpp>

namespace vh::app {

/// Adds the `pacs` subcommand to `app`; after parsing, `handler` is set when it was given and
/// returns the exit status (0 done, 1 error, with the message on stderr).
CLI::App* addPacsSubcommand(CLI::App& app, std::function<int()>& handler);

}  // namespace vh::app
