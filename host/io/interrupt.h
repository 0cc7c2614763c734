// SIGINT / SIGTERM for long commands: the first signal asks the command to stop after the work
// in flight (a frame, a progressive pass) and to write what is done; a second one exits at
// once. Exiting at once must still leave no partial output, so the handler removes what the
// rest of the program registered here: the temporary file being written, the --out lock file,
// and the folders the run created (if still empty). The registry is fixed-size plain memory
// because a signal handler may only touch such memory and call async-signal-safe functions.
#pragma once

namespace px {

// Installs the handlers (idempotent). Commands that never check interrupted() should not call
// this: they keep the default behaviour (terminate at once).
void install_interrupt_handlers();

// The signal number of the first SIGINT/SIGTERM received, 0 if none.
int interrupt_signal();
inline bool interrupted() { return interrupt_signal() != 0; }
// Exit status for an interrupted run: 128 + signal number (130 for SIGINT, 143 for SIGTERM).
int interrupt_exit_code();
// "SIGINT" / "SIGTERM".
const char* interrupt_signal_name();

// Registrations for the second-signal exit. Each slot holds one path; paths longer than the
// slot (4 KiB) are not registered (the file is then left behind by a hard exit, never a
// truncated file under a final name, since final names only ever appear by rename).
// Temporary files being written (up to 8 at once: the image being encoded plus streamed reports).
// Returns the slot to unregister, -1 if none was free or the path too long.
int register_partial_file(const char* path);
void unregister_partial_file(int slot);
void register_lock_file(const char* path);
void unregister_lock_file();
void register_created_dir(const char* path);  // removed (rmdir: only if empty) in reverse order
void unregister_created_dirs();

// Test hook: behaves as if `signal` had been received once.
void simulate_interrupt_for_testing(int signal);

}  // namespace px
