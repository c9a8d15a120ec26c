"""An IOTA whose one input takes at most one value a second: a ROS 2 topic published faster
must be refused (switching time) and recorded as such."""
from iotad import Float, Input, Iota


class SlowInput(Iota):
    level = Input(Float, switching=1.0)

    def init(self):
        self.last = None

    @level.input
    def took(self, value):
        self.last = value
