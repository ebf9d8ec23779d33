"""Per-task VMs from a memory snapshot: a generic QEMU runner in a container of ours (`fixtures/images/vm-runner/`).

A golden is prepared once: its disk is cold-booted, the guest's control server answers, the memory is saved to a
file. Every task's VM is then a runner container that makes a copy-on-write overlay of the golden disk and loads
that memory (`-incoming`): the guest resumes where it was saved, logged on, its control server answering, in
seconds. Nothing of a task outlives its container.

Modules (host side unless said):
  profile      the machine profile (all that must match between save and restore) and the QEMU command line
  golden       the golden folder, its READY record and the rules a restore obeys
  qmp          a small QMP client (runner side)
  runner       PID 1 of a runner container: `prepare` and `restore` (runner side)
  prepare      `prepare_snapshot(golden, profile, ...)`: a runner container in prepare mode
  backend      `vm_backend(platform, golden, profile)`: a device backend of restored VMs; `task_options(...)`
  windows      dockur/windows 6.05's Windows 10 machine as a profile; `prepare_windows(storage, ...)` (used by
               `devices/windows/real.py`: the kvm backend's tasks are restored VMs)
  testguest    the small Linux guest that proves it all under TCG (`tests/test_vm_runner.py`)
  guest_server a minimal control server for a Linux guest (guest side)

Nothing is imported here: the runner's and the guest's images carry only what they run.
"""
