#pragma once
/// @file
/// Turns VTK error and warning messages raised during a load into data the loader can throw
/// as one LoadError, instead of text on stderr. Private to vh::io.

#include <string>
#include <vector>

#include <vtkObject.h>
#include <vtkSmartPointer.h>

namespace vh::io::detail {

/// RAII scope that collects VTK messages raised on this thread while it lives.
///
/// Two routes: observers on the objects passed to watch() (ErrorEvent and WarningEvent; VTK
/// raises these instead of logging when an observer exists, so nothing reaches stderr), and a
/// process-wide vtkOutputWindow installed once, which collects the text of unobserved VTK
/// objects on a thread with an active capture (VTK 9.1 still logs those to stderr through
/// vtkLogger, so every object that can fail should be watched) and otherwise behaves like the
/// window it replaced. Scopes nest; the innermost one collects.
class VtkErrorCapture {
 public:
  VtkErrorCapture();
  ~VtkErrorCapture();
  VtkErrorCapture(const VtkErrorCapture&) = delete;
  VtkErrorCapture& operator=(const VtkErrorCapture&) = delete;

  /// Observes ErrorEvent and WarningEvent on `object` until this scope ends (keeps it alive).
  void watch(vtkObject* object);

  bool hasErrors() const noexcept { return !errors_.empty(); }
  /// Error messages, cleaned of VTK's "ERROR: In file, line" and "Class (0x...):" prefixes.
  const std::vector<std::string>& errors() const noexcept { return errors_; }
  const std::vector<std::string>& warnings() const noexcept { return warnings_; }
  /// The first error, or "" when none.
  std::string firstError() const { return errors_.empty() ? std::string() : errors_.front(); }
  void clear() noexcept {
    errors_.clear();
    warnings_.clear();
  }

  // Used by the observers and the output window.
  void addError(const char* text);
  void addWarning(const char* text);
  /// The innermost capture active on this thread, or nullptr.
  static VtkErrorCapture* current() noexcept;

 private:
  struct Observation {
    vtkSmartPointer<vtkObject> object;  // kept alive until the observers are removed
    unsigned long error_tag;
    unsigned long warning_tag;
  };
  std::vector<std::string> errors_;
  std::vector<std::string> warnings_;
  std::vector<Observation> observations_;
  VtkErrorCapture* previous_ = nullptr;
};

/// Removes VTK's message decoration ("ERROR: In /path/x.cxx, line 12\nvtkX (0x1234): text").
std::string cleanVtkMessage(const char* text);

}  // namespace vh::io::detail
