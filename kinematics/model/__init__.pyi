from .loops import Closure as Closure
from .loops import LoopSpec as LoopSpec
from .loops import load_loop_spec as load_loop_spec
from .robot import Dof as Dof
from .robot import Robot as Robot
from .robot import load_robot as load_robot
from .robot import parser_agreement as parser_agreement
from .robot import robot_names as robot_names
