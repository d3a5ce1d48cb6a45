"""Cycles per function and activity id from a JA_AVR_PROFILE file (README.md "Profile").

usage: profile_report.py IMAGE.elf PROFILE.txt [LOOPS]
LOOPS (the report's "loops") turns the sums into cycles per loop.
"""
import bisect
import collections
import subprocess
import sys


def symbols(elf: str) -> list[tuple[int, str]]:
    """Code symbols of the ELF (address, demangled name), by address."""
    out = subprocess.run(["avr-nm", "-C", "-n", "-S", elf], capture_output=True, text=True,
                         check=True).stdout
    syms = []
    for line in out.splitlines():
        parts = line.split(None, 3)
        if len(parts) == 4 and parts[2] in "tTwW":
            syms.append((int(parts[0], 16), parts[3]))
    return sorted(syms)


def main(argv: list[str]) -> int:
    if len(argv) not in (3, 4):
        sys.stderr.write(__doc__ or "")
        return 2
    syms = symbols(argv[1])
    addrs = [a for a, _ in syms]
    loops = float(argv[3]) if len(argv) == 4 else 1.0
    by_function: collections.Counter[tuple[str, str]] = collections.Counter()
    by_id: collections.Counter[str] = collections.Counter()
    with open(argv[2]) as f:
        for line in f:
            pc_hex, aid, cycles = line.split()
            i = bisect.bisect_right(addrs, int(pc_hex, 16)) - 1
            name = syms[i][1] if i >= 0 else "?"
            by_function[(name, aid)] += int(cycles)
            by_id[aid] += int(cycles)
    for aid in sorted(by_id, key=int):
        sys.stdout.write(f"id {aid}: {by_id[aid] / loops:.0f}\n")
        for (name, a), c in by_function.most_common():
            if a == aid and c / loops >= 20:
                sys.stdout.write(f"  {c / loops:8.0f}  {name[:110]}\n")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
