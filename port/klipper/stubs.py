"""Stand-ins for the few Klipper objects port/klipper/abbe.py calls (config, printer,
G-code dispatcher, G-code command, the next move transform), so the module can be driven
outside Klipper: by its unit tests (host_tools/tests/ports/test_klipper_module.py) and by
the host-cost bench (bench_cost.py). Klipper's own batch mode is the real proof
(tests/klipper_batch.py)."""


class ConfigError(Exception):
    pass


class CommandError(Exception):
    pass


class Config:
    """``config.get*`` over a dict of values, with the module's defaults."""

    def __init__(self, printer, values):
        self.printer, self.values = printer, values

    def get_printer(self):
        return self.printer

    def get(self, key, default=None):
        return self.values.get(key, default)

    def getboolean(self, key, default=None):
        return bool(self.values.get(key, default))

    def getfloat(self, key, default=None, **_):
        return float(self.values.get(key, default))

    def getint(self, key, default=None, **_):
        return int(self.values.get(key, default))

    def error(self, msg):
        return ConfigError(msg)


class Gcode:
    """Registers commands by name and keeps what was said."""

    def __init__(self):
        self.commands = {}
        self.said = []

    def register_command(self, name, fn, desc=None):
        self.commands[name] = fn

    def respond_info(self, msg):
        self.said.append(msg)


class Gcmd:
    """One G-code command's parameters."""

    def __init__(self, params, gcode):
        self.params, self.gcode = params, gcode

    def get(self, key, default=None):
        return self.params.get(key, default)

    def respond_info(self, msg):
        self.gcode.said.append(msg)

    def error(self, msg):
        return CommandError(msg)


class Printer:
    """lookup_object over a dict (``gcode`` always there), event handlers kept."""
    command_error = CommandError

    def __init__(self, **objects):
        self.gcode = Gcode()
        self.objects = {"gcode": self.gcode, **objects}
        self.handlers = {}

    def lookup_object(self, name, default=None):
        return self.objects.get(name, default)

    def register_event_handler(self, event, fn):
        self.handlers[event] = fn


class Recorder:
    """The next transform: records every move abbe hands on."""

    def __init__(self):
        self.moves = []
        self.pos = [0.0, 0.0, 0.0, 0.0]

    def move(self, pos, speed):
        self.moves.append(list(pos))
        self.pos = list(pos)

    def get_position(self):
        return list(self.pos)
