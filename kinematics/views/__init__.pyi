from . import meshcat as meshcat
from . import plots as plots
