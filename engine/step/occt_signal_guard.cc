#include "engine/step/occt_signal_guard.h"

#include <signal.h>

#include <OSD.hxx>
#include <array>
#include <mutex>

namespace mktree {

namespace {

// What OSD::SetSignal sets; the last three are given back at once (Ctrl-C stays the program's).
constexpr std::array<int, 8> kOcctSignals{SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGSYS, SIGINT, SIGHUP, SIGQUIT};
constexpr size_t kKeptSignals = 5;

struct SavedHandlers {
  std::mutex mutex;
  int guards = 0;
  std::array<struct sigaction, kOcctSignals.size()> previous{};
};

SavedHandlers& Saved() {
  static SavedHandlers saved;
  return saved;
}

}  // namespace

OcctSignalGuard::OcctSignalGuard() {
  SavedHandlers& s = Saved();
  std::lock_guard<std::mutex> lock(s.mutex);
  if (s.guards++ > 0) return;
  for (size_t i = 0; i < kOcctSignals.size(); ++i) ::sigaction(kOcctSignals[i], nullptr, &s.previous[i]);
  OSD::SetSignal(OSD_SignalMode_Set, /*theFloatingSignal=*/false);
  for (size_t i = kKeptSignals; i < kOcctSignals.size(); ++i)
    ::sigaction(kOcctSignals[i], &s.previous[i], nullptr);
}

OcctSignalGuard::~OcctSignalGuard() {
  SavedHandlers& s = Saved();
  std::lock_guard<std::mutex> lock(s.mutex);
  if (--s.guards > 0) return;
  for (size_t i = 0; i < kKeptSignals; ++i) ::sigaction(kOcctSignals[i], &s.previous[i], nullptr);
}

}  // namespace mktree
