#include "vtk_error_capture.h"

#include <cstring>
#include <mutex>
#include <regex>

#include <vtkAlgorithm.h>
#include <vtkCallbackCommand.h>
#include <vtkExecutive.h>
#include <vtkCommand.h>
#include <vtkObjectFactory.h>
#include <vtkOutputWindow.h>
#include <vtkSmartPointer.h>

namespace vh::io::detail {
namespace {

thread_local VtkErrorCapture* t_current = nullptr;

/// Diverts VTK text to the active capture of the calling thread. Outside captures it behaves
/// like the window it replaced: VTK's default window (our own base class, so that VTK's "already
/// logged" bookkeeping applies and nothing is printed twice) or an application's window.
class CapturingOutputWindow : public vtkOutputWindow {
 public:
  static CapturingOutputWindow* New();
  vtkTypeMacro(CapturingOutputWindow, vtkOutputWindow)

  void setPrevious(vtkOutputWindow* previous) {
    // A plain vtkOutputWindow is replaced by our base class behaviour.
    if (previous != nullptr && std::strcmp(previous->GetClassName(), "vtkOutputWindow") != 0) {
      previous_ = previous;
    }
  }

  void DisplayErrorText(const char* text) override {
    if (auto* c = VtkErrorCapture::current()) {
      c->addError(text);
    } else if (previous_) {
      previous_->DisplayErrorText(text);
    } else {
      vtkOutputWindow::DisplayErrorText(text);
    }
  }
  void DisplayWarningText(const char* text) override {
    if (auto* c = VtkErrorCapture::current()) {
      c->addWarning(text);
    } else if (previous_) {
      previous_->DisplayWarningText(text);
    } else {
      vtkOutputWindow::DisplayWarningText(text);
    }
  }
  void DisplayGenericWarningText(const char* text) override {
    if (auto* c = VtkErrorCapture::current()) {
      c->addWarning(text);
    } else if (previous_) {
      previous_->DisplayGenericWarningText(text);
    } else {
      vtkOutputWindow::DisplayGenericWarningText(text);
    }
  }
  void DisplayText(const char* text) override {
    if (VtkErrorCapture::current() != nullptr) return;
    if (previous_) {
      previous_->DisplayText(text);
    } else {
      vtkOutputWindow::DisplayText(text);
    }
  }
  void DisplayDebugText(const char* text) override {
    if (VtkErrorCapture::current() != nullptr) return;
    if (previous_) {
      previous_->DisplayDebugText(text);
    } else {
      vtkOutputWindow::DisplayDebugText(text);
    }
  }

 private:
  vtkSmartPointer<vtkOutputWindow> previous_;  // an application's window, if any
};
vtkStandardNewMacro(CapturingOutputWindow);

void installOutputWindowOnce() {
  static std::once_flag once;
  std::call_once(once, [] {
    auto window = vtkSmartPointer<CapturingOutputWindow>::New();
    window->setPrevious(vtkOutputWindow::GetInstance());
    vtkOutputWindow::SetInstance(window);
  });
}

void onError(vtkObject*, unsigned long, void* client, void* call) {
  static_cast<VtkErrorCapture*>(client)->addError(static_cast<const char*>(call));
}
void onWarning(vtkObject*, unsigned long, void* client, void* call) {
  static_cast<VtkErrorCapture*>(client)->addWarning(static_cast<const char*>(call));
}

}  // namespace

std::string cleanVtkMessage(const char* text) {
  if (text == nullptr) return "unknown VTK error";
  std::string s(text);
  // "ERROR: In /path/file.cxx, line 123\n" or "Warning: In ..., line N\n"
  static const std::regex kLocation(R"(^\s*(ERROR|Warning|Generic Warning): In [^\n]*, line \d+\n)");
  // "vtkNrrdReader (0x55d...): "
  static const std::regex kObject(R"(^\s*\w+ \(0x[0-9a-fA-F]+\): )");
  // Messages relayed from one VTK object to another carry several such prefixes.
  for (int pass = 0; pass < 4; ++pass) {
    const std::string before = s;
    s = std::regex_replace(s, kLocation, "");
    s = std::regex_replace(s, kObject, "");
    if (s == before) break;
  }
  while (!s.empty() && (s.back() == '\n' || s.back() == ' ' || s.back() == '\r')) s.pop_back();
  return s.empty() ? std::string("unknown VTK error") : s;
}

VtkErrorCapture::VtkErrorCapture() : previous_(t_current) {
  installOutputWindowOnce();
  t_current = this;
}

VtkErrorCapture::~VtkErrorCapture() {
  for (const auto& o : observations_) {
    o.object->RemoveObserver(o.error_tag);
    o.object->RemoveObserver(o.warning_tag);
  }
  t_current = previous_;
}

void VtkErrorCapture::watch(vtkObject* object) {
  if (object == nullptr) return;
  // An algorithm's pipeline errors ("returned failure for request") come from its executive.
  if (auto* algorithm = vtkAlgorithm::SafeDownCast(object)) watch(algorithm->GetExecutive());
  auto error_cb = vtkSmartPointer<vtkCallbackCommand>::New();
  error_cb->SetCallback(&onError);
  error_cb->SetClientData(this);
  auto warning_cb = vtkSmartPointer<vtkCallbackCommand>::New();
  warning_cb->SetCallback(&onWarning);
  warning_cb->SetClientData(this);
  Observation o{object, object->AddObserver(vtkCommand::ErrorEvent, error_cb),
                object->AddObserver(vtkCommand::WarningEvent, warning_cb)};
  observations_.push_back(o);
}

void VtkErrorCapture::addError(const char* text) { errors_.push_back(cleanVtkMessage(text)); }
void VtkErrorCapture::addWarning(const char* text) { warnings_.push_back(cleanVtkMessage(text)); }

VtkErrorCapture* VtkErrorCapture::current() noexcept { return t_current; }

}  // namespace vh::io::detail
