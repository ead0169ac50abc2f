from .controller import Controller as Controller
from .controller import GuidanceParams as GuidanceParams
from .simulation import EXPERIMENTS as EXPERIMENTS
from .simulation import Experiment as Experiment
from .simulation import Run as Run
from .simulation import run_experiment as run_experiment
from .simulation import simulate as simulate
