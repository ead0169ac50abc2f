from .closed_form import DeltaParams as DeltaParams
from .mechanism import Delta as Delta
from .urdf import read_params as read_params
