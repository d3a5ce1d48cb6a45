"""The virtual boards: the firmware run on this machine behind a pseudo-terminal, so the host
talks to it exactly as to hardware (`sim://native`, `sim://avr`; docs/design.md §1).

- `options`: what a board is started with (`LaunchOptions`), the `sim://` URL query that sets
  it, and the command-line options every board takes.
- `launchers`: the table of boards (`SIM_LAUNCHERS`) and the rig and motion each one plays.
- `process`: a board as a process (its `PTY <path>` contract) and its work folder.
- `guard.py`: the script every board runs behind, so none outlives its host.
- `sim_devices`: the virtual I2C devices the boards serve, from Python through their C ABI.

The motion the boards play comes from `jointangle.sim` (motion simulation only).
"""
