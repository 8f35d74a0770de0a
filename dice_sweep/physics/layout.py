"""The kernels' data layout, defined once: state columns, status and outcome codes, counters,
segment records and their capacities, contact-model and integrator codes.

Module-level ints are compile-time constants in numba, so the kernels index with them at no
cost. No numba here: anything may import this module without compiling. The parameter vectors
``fpar``/``ipar`` have their own layout in :mod:`dice_sweep.physics.params`.
"""

from dice_sweep.config import CONTACT_MODELS, INTEGRATOR_METHODS
from dice_sweep.effects import FRICTION_RULES, RESTITUTION_LAWS

# --- a roll's initial state (geometric centre, SI) -----------------------------------------
STATE_COLUMNS = ("x0", "y0", "phi0", "vx0", "vy0", "omega0")

# --- outcome and status of a roll -----------------------------------------------------------
UNDECIDED = -1  # outcome of a roll without an answer (see its status)
PATH_CUT = -2  # sample_batch only: the roll needed more than SAMPLE_RECORDS segments; samples past them are NaN

STATUS_DECIDED = 0
STATUS_T_MAX = 1
STATUS_EVENT_BUDGET = 2
STATUS_BALANCED = 3
STATUS_STALLED = 4
STATUS_PROPPED = 5  # at rest leaning on a wall, no side decided (a "cocked" die: no answer)
STATUS_NAMES = ("decided", "t_max", "event_budget", "balanced", "stalled", "propped")

# --- event counters: one column each --------------------------------------------------------
COUNT_COLUMNS = ("impacts", "wall_impacts", "corner_fallbacks", "pivots", "energy_clips", "multi_contacts")
C_IMPACTS = 0
C_WALL = 1
C_FALLBACK = 2  # the paper's law undefined, the impulse at the corner used
C_PIVOTS = 3
C_CLIPS = 4  # energy clips of the rigid law
C_MULTI = 5  # impacts of two contacts at once

# --- segment records: one row per stretch of motion, enough to re-create the path ----------
SEG_FLIGHT = 0
SEG_PIVOT = 1  # closed-form (conservative, sticking) pivot
SEG_END = 2
SEG_PIVOT_ODE = 3  # pivot followed by the ODE (slip, drag, or a loaded die turning back)
SEG_SLIDE = 4  # lying flat on a side and sliding to a stop under Coulomb friction
SEG_LADDER = 5  # sliding on a table corner (REC_CORNER) and a wall corner (REC_PX) of the wall REC_CHI (+-1)
EVENT_START = 0
EVENT_IMPACT = 1
EVENT_LIFTOFF = 2
REC_T = 0
REC_KIND = 1
REC_STATE = 2  # six columns: x, y, phi, vx, vy, omega at the start of the segment
REC_CORNER = 8
REC_PX = 9
REC_CHI = 10
REC_CHI_END = 11
REC_ENERGY = 12
REC_EVENT = 13
REC_WIDTH = 14

ROLL_RECORDS = 100_000  # records a single roll keeps (dice_sweep.roll, simulate-drops' first pass)
SAMPLE_RECORDS = 4096  # records per roll of sample_batch (a fit's segments need a few)

# --- codes of the config's choices ------------------------------------------------------------
MODELS = {name: code for code, name in enumerate(CONTACT_MODELS)}
MODEL_PAPER = MODELS["paper"]
MODEL_RIGID = MODELS["rigid"]
METHODS = {name: code for code, name in enumerate(INTEGRATOR_METHODS)}
METHOD_EVENT = METHODS["event"]
METHOD_FIXED_STEP = METHODS["fixed_step"]
FRICTION_RULE_AIMED = FRICTION_RULES.index("aimed")  # ipar[IP_FRICTION_RULE]: the cone's edge on the aimed impulse's side
FRICTION_RULE_SLIDING = FRICTION_RULES.index("sliding")  # the textbook branch: opposing the incoming slip
FRICTION_RULE_EXACT = FRICTION_RULES.index("exact")  # Routh's integration over the normal impulse
RESTITUTION_NEWTON = RESTITUTION_LAWS.index("newton")  # ipar[IP_RESTITUTION]
RESTITUTION_ENERGETIC = RESTITUTION_LAWS.index("energetic")
