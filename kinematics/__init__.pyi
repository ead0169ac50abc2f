from .analyses.columns import column_volume as column_volume
from .analyses.singularities import singular_loci as singular_loci
from .analyses.workspace import measure_workspace as measure_workspace
from .errors import KinematicsError as KinematicsError
from .mechanisms import Mechanism as Mechanism
from .mechanisms import mechanism_of as mechanism_of
from .model.robot import Robot as Robot
from .model.robot import load_robot as load_robot

__version__: str
