// app/runtime's public headers stay free of VTK (and Qt). This file includes every one
// of them and is compiled by tests/app/runtime/CMakeLists.txt with only the include folders of
// the project's haptics, io, datasets and runtime headers, Eigen and nlohmann-json: a header that
// pulls in a VTK or Qt header fails the build.
#include "vh/runtime/device.h"
#include "vh/runtime/drill_report.h"
#include "vh/runtime/haptic_snapshot.h"
#include "vh/runtime/haptic_thread.h"
#include "vh/runtime/passivity_port.h"
#include "vh/runtime/placement.h"
#include "vh/runtime/realtime.h"
#include "vh/runtime/recording.h"
#include "vh/runtime/replay.h"
#include "vh/runtime/runner.h"
#include "vh/runtime/sample_filter.h"
#include "vh/runtime/sample_ring.h"
#include "vh/runtime/scene.h"
#include "vh/runtime/session.h"
#include "vh/runtime/session_metadata.h"
#include "vh/runtime/sha256.h"
#include "vh/runtime/snapshot_channel.h"
#include "vh/runtime/thread_timing.h"
#include "vh/runtime/tick_record.h"
#include "vh/runtime/tick_ring.h"
#include "vh/runtime/trajectory.h"
#include "vh/runtime/triple_buffer.h"

#ifdef VTK_VERSION
#error "a runtime header included VTK"
#endif
#ifdef QT_VERSION
#error "a runtime header included Qt"
#endif
