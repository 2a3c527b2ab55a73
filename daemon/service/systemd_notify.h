// systemd's readiness and watchdog protocol (sd_notify(3)) without libsystemd: datagrams to the
// socket named by $NOTIFY_SOCKET. Outside systemd (no such variable) every call does nothing.
#pragma once
#include <chrono>
#include <string>

namespace mm::service {

// Sends `state` ("READY=1", "STOPPING=1", "WATCHDOG=1", "STATUS=..."); false when there is no
// socket or the send failed (never fatal: the daemon runs the same without systemd).
bool notify_systemd(const std::string& state);

// How often to send WATCHDOG=1: half of $WATCHDOG_USEC (for this process, $WATCHDOG_PID), or zero
// when systemd asked for no watchdog.
std::chrono::milliseconds watchdog_interval();

}  // namespace mm::service
