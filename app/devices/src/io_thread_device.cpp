#include "vh/devices/io_thread_device.h"

#include <utility>

namespace vh::devices {

IoThreadDevice::~IoThreadDevice() { stopIoThread(); }

std::string IoThreadDevice::problem() const {
  const std::lock_guard<std::mutex> lock(problem_mutex_);
  return problem_;
}

void IoThreadDevice::startIoThread(std::function<void()> loop) {
  stop_.store(false, std::memory_order_release);
  connection_.fetch_add(1, std::memory_order_acq_rel);
  connected_.store(true, std::memory_order_release);
  io_ = std::thread(std::move(loop));
}

void IoThreadDevice::stopIoThread() noexcept {
  stop_.store(true, std::memory_order_release);
  if (io_.joinable()) io_.join();
}

void IoThreadDevice::setProblem(std::initializer_list<std::string_view> parts) noexcept {
  try {
    std::size_t size = 0;
    for (const std::string_view part : parts) size += part.size();
    std::string text;
    text.reserve(size);
    for (const std::string_view part : parts) text.append(part);
    const std::lock_guard<std::mutex> lock(problem_mutex_);
    problem_ = std::move(text);
  } catch (...) {
    // No memory for the text (or no lock): the previous text stays.
  }
}

}  // namespace vh::devices
