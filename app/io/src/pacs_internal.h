#pragma once
/// @file
/// The PACS client's private side. The operations of vh/io/pacs.h as they run in the calling
/// process (pacs.cpp): the DICOM network process (pacs_process.cpp) runs them, so that a server's
/// answer that crashes DCMTK's parser (a sequence nested 100,000 deep overflows its recursive
/// reader's stack) or asks for absurd memory ends that process, not the application. And what
/// the client makes of a C-FIND response's identifier: the study or series record it lists,
/// apart so that the fuzz target can feed it datasets that no server sent
/// (tests/fuzz/fuzz_pacs_response.cpp).

#include <string>
#include <string_view>

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

/// `s` without leading and trailing blanks (space, tab, CR, LF): how the client reads its
/// settings and a server's text.
std::string pacsTrim(std::string_view s);

/// "PACS CALLED at HOST:PORT: " and `what`: the error that names the server.
PacsError pacsError(const PacsServer& server, const std::string& what);

/// The settings an association needs, checked before any connection (host, port, AE titles,
/// timeout). @throws PacsError naming the first one that is wrong.
void checkPacsServer(const PacsServer& server);

/// pacsEcho() in this process. @throws PacsError as pacsEcho().
void pacsEchoInProcess(const PacsServer& server);
/// pacsFindStudies() in this process. @throws PacsError as pacsFindStudies().
std::vector<PacsStudy> pacsFindStudiesInProcess(const PacsServer& server, const PacsStudyQuery& query);
/// pacsFindSeries() in this process. @throws PacsError as pacsFindSeries().
std::vector<PacsSeries> pacsFindSeriesInProcess(const PacsServer& server, const std::string& study_uid,
                                                const std::string& modality);
/// pacsFindSeriesByUid() in this process. @throws PacsError as pacsFindSeriesByUid().
PacsSeries pacsFindSeriesByUidInProcess(const PacsServer& server, const std::string& series_uid);
/// pacsRetrieveSeries() in this process (options.cancel and options.progress called on this
/// thread). @throws PacsError as pacsRetrieveSeries().
PacsRetrieveResult pacsRetrieveSeriesInProcess(const PacsServer& server, const std::string& study_uid,
                                               const std::string& series_uid, const std::filesystem::path& out_dir,
                                               const PacsRetrieveOptions& options);

/// The reader program's `pacs OP REQUEST OUT` mode, the DICOM network process: runs operation
/// OP (echo, find-studies, find-series, find-series-by-uid, retrieve) with the settings and
/// arguments of the REQUEST file and writes its result to OUT; prints "progress RECEIVED TOTAL
/// FAILED FILE" after each file retrieved, and "error MESSAGE" before exiting 1 on a PacsError.
/// SIGUSR1 asks a retrieval to stop (PacsRetrieveOptions::cancel). Its address space is bounded
/// by the memory this computer has free, so that a length field asking for gigabytes ends this
/// process's allocation instead of pushing the machine into swap.
/// @return the exit status: 0 done, 1 a PacsError, 2 a usage error.
int pacsProcessMain(int argc, char** argv);

}  // namespace vh::io::detail
