from .closed_form import P2USParams as P2USParams
from .mechanism import P2US as P2US
from .urdf import read_params as read_params
