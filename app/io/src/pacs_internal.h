#pragma once
/// @file
/// What the PACS client (pacs.cpp) makes of a C-FIND response's identifier: the study or series
/// record it lists. Private to vh::io; apart so that the fuzz target can feed it datasets that no
/// server sent (tests/fuzz/fuzz_pacs_response.cpp).

#include "vh/io/pacs.h"

class DcmItem;

namespace vh::io::detail {

/// The study a STUDY-level C-FIND response's identifier `ds` describes: each attribute of
/// PacsStudy trimmed, empty when absent or unreadable; Number of Study Related Series -1 unless
/// it is a whole non-negative number. `ds` may be null (every field then empty or -1). Never
/// throws but std::bad_alloc.
PacsStudy studyFromResponse(DcmItem* ds);

/// The series a SERIES-level C-FIND response's identifier `ds` describes, as studyFromResponse():
/// Series Number and Number of Series Related Instances -1 unless whole non-negative numbers.
PacsSeries seriesFromResponse(DcmItem* ds);

}  // namespace vh::io::detail
