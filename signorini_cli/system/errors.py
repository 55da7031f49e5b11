"""The one line a failure of bad input or surroundings ends with: `signorini: error: SOURCE: MESSAGE`."""
import sys


def print_error(source, message, program="signorini"):
    """Print the error line to stderr (no source: `program: error: MESSAGE`), the message joined into
    one line whatever it holds."""
    if isinstance(message, OSError) and message.strerror:  # not "[Errno 2] No such file ...: 'x'"
        message = message.strerror[:1].lower() + message.strerror[1:] + (
            f": {message.filename}" if message.filename and str(message.filename) not in str(source) else "")
    text = " ".join(str(message).split("\n"))
    print(f"{program}: error: " + (f"{source}: {text}" if source else text), file=sys.stderr)
