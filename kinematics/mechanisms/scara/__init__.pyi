from .closed_form import ScaraParams as ScaraParams
from .mechanism import Scara as Scara
