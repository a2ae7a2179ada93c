"""Errors the CLI turns into one line and a distinct exit code (never a traceback)."""


class CodegenError(Exception):
    """Base class: a problem the user can fix. `exit_code` is what the CLI returns."""

    exit_code = 2


class ModelError(CodegenError):
    """The model (file or API) is malformed, uses an undeclared name, or is not flat."""


class ScenarioError(CodegenError):
    """A scenario file or option is malformed."""


class SetupError(CodegenError):
    """A tool the command needs (compiler, emulator) is missing or broken."""


class MismatchError(CodegenError):
    """Generated C disagrees with the Python reference."""

    exit_code = 1
