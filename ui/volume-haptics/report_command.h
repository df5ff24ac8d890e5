#pragma once
/// @file
/// `volume-haptics report`: a session recording to a self-contained HTML report (optionally
/// against a reference recording of the same scene), or a folder of recordings to a cohort CSV
/// table. Headless: the charts are drawn on Qt's offscreen platform, no display is needed.

#include <functional>

#include <CLI/CLI.hpp>

namespace vh::app {

/// Adds the `report` subcommand to `app`; after parsing, `handler` is set when it was given and
/// returns the exit status (0 done, 1 error, with the message on stderr).
CLI::App* addReportSubcommand(CLI::App& app, std::function<int()>& handler);

}  // namespace vh::app
