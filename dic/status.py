"""Per-point status codes.

A point that cannot be measured carries a code saying why, in its own array;
values such as ZNCC are NaN there, never a fake number.
"""

from enum import IntEnum


class Status(IntEnum):
    OK = 0
    OUTSIDE_REFERENCE = 1   # the subset around the point leaves the reference image
    FLAT_REFERENCE = 2      # no texture in the reference subset
    OUTSIDE_TARGET = 3      # every candidate position leaves the deformed image
    FLAT_TARGET = 4         # no texture where the subset lands in the deformed image
    NOT_CONVERGED = 5       # iterative refinement hit its iteration cap or diverged
    BAD_GUESS = 6           # the initial guess for this point is NaN or infinite
    LOW_CORRELATION = 7     # best match below the ZNCC acceptance threshold
    POOR_TEXTURE = 8        # too little texture, or texture in one direction only, to pin the match
    OUTLIER = 9             # disagrees with its neighbours (normalised median test)
    NOT_IN_KEY_FRAME = 10   # could not be placed in the frame that became the reference (incremental correlation)
    SEPARATED = 11          # its material separated (fracture): no longer tracked

    @property
    def description(self) -> str:
        return _DESCRIPTIONS[self]


# The same codes as plain ints for numba kernels (a module-level int is a compile-time constant
# there, an IntEnum member is not): kernel modules import these rather than write the numbers.
OK = int(Status.OK)
OUTSIDE_REFERENCE = int(Status.OUTSIDE_REFERENCE)
FLAT_REFERENCE = int(Status.FLAT_REFERENCE)
OUTSIDE_TARGET = int(Status.OUTSIDE_TARGET)
FLAT_TARGET = int(Status.FLAT_TARGET)
NOT_CONVERGED = int(Status.NOT_CONVERGED)
BAD_GUESS = int(Status.BAD_GUESS)
LOW_CORRELATION = int(Status.LOW_CORRELATION)
POOR_TEXTURE = int(Status.POOR_TEXTURE)
OUTLIER = int(Status.OUTLIER)
NOT_IN_KEY_FRAME = int(Status.NOT_IN_KEY_FRAME)
SEPARATED = int(Status.SEPARATED)


_DESCRIPTIONS = {
    Status.OK: "measured",
    Status.OUTSIDE_REFERENCE: "subset leaves the reference image",
    Status.FLAT_REFERENCE: "reference subset has no texture",
    Status.OUTSIDE_TARGET: "subset leaves the deformed image",
    Status.FLAT_TARGET: "deformed subset has no texture",
    Status.NOT_CONVERGED: "sub-pixel refinement did not converge",
    Status.BAD_GUESS: "initial guess is not finite",
    Status.LOW_CORRELATION: "best ZNCC below the acceptance threshold",
    Status.POOR_TEXTURE: "subset has too little texture, or texture in one direction only",
    Status.OUTLIER: "displacement disagrees with the neighbouring points",
    Status.NOT_IN_KEY_FRAME: "not measured when the reference was updated, and its neighbours could not place it",
    Status.SEPARATED: "its material separated (fracture): no longer tracked",
}
