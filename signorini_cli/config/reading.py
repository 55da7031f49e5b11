"""Reading YAML: duplicate keys refused, YAML 1.2 numbers, bounded size and nesting; the command line's
`KEY=VALUE` overrides set into the raw mapping before it is validated."""
import re

import yaml

from .schema import ConfigError

MAX_BYTES = 1 << 20  # a config is a page of YAML: 1 MiB is far beyond any real one


def apply_override(raw, item):
    """Set `a.b.c=value` in the raw mapping; the value is parsed as YAML, then validated as usual."""
    name, sep, value = item.partition("=")
    if not sep or not name.strip():
        raise ConfigError("--set", f"expected KEY=VALUE, got {item!r}")
    try:
        set_path(raw, name.strip(), yaml_load(value))
    except yaml.YAMLError as err:
        problem = getattr(err, "problem", None) or err
        raise ConfigError(f"--set {name.strip()}", f"{value!r} is not a YAML value: {problem}") from None


def set_path(raw, dotted, value):
    """raw[a][b][c] = value for dotted = "a.b.c", creating the mappings on the way; a mapping that holds the
    rest as one dotted key (a map's grid: `epsilon.theta: [...]`) gets it replaced there."""
    parts = dotted.split(".")
    node = raw
    for i, part in enumerate(parts[:-1]):
        if ".".join(parts[i:]) in node:
            node[".".join(parts[i:])] = value
            return
        child = node.get(part)
        if child is not None and not isinstance(child, dict):
            raise ConfigError(".".join(parts[:i + 1]), "is not a mapping, cannot set a sub-key")
        if child is None:
            child = node[part] = {}
        node = child
    node[parts[-1]] = value


class _Loader(yaml.SafeLoader):
    """Safe YAML that rejects duplicate keys (PyYAML keeps the last one silently) and reads 1e-8
    as a number, as YAML 1.2 does (PyYAML's YAML 1.1 reads it as a string)."""

    def construct_mapping(self, node, deep=False):
        seen = set()
        for key_node, _ in node.value:
            if isinstance(key_node, yaml.ScalarNode) and key_node.tag != "tag:yaml.org,2002:merge":
                if key_node.value in seen:
                    raise yaml.constructor.ConstructorError(
                        "while constructing a mapping", node.start_mark,
                        f"found duplicate key {key_node.value!r}", key_node.start_mark)
                seen.add(key_node.value)
        return super().construct_mapping(node, deep=deep)


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$"), list("-+0123456789."))


def yaml_dump(data, allow_unicode=True):
    """Plain data -> block-style YAML text, keys in order (libyaml's emitter where installed: the same text,
    four times faster, which a map's points, each written as it is resolved, notice)."""
    return yaml.dump(data, Dumper=getattr(yaml, "CSafeDumper", yaml.SafeDumper), sort_keys=False,
                     allow_unicode=allow_unicode)


def yaml_load(text):
    """YAML text -> Python data (safe: plain data only). Bad characters and excessive nesting are
    reported as YAML errors with a line and column, never as Python exceptions."""
    try:
        return _compose_checked(text)
    except yaml.reader.ReaderError as err:
        line = text.count("\n", 0, err.position)
        column = err.position - (text.rfind("\n", 0, err.position) + 1)
        character = f"#x{err.character:04x}" if isinstance(err.character, int) else repr(err.character)
        mark = yaml.Mark("config", err.position, line, column, None, None)
        raise yaml.MarkedYAMLError(problem=f"unacceptable character {character}: {err.reason}",
                                   problem_mark=mark) from None
    except RecursionError:
        raise ConfigError("", "YAML nested too deeply") from None


def _compose_checked(text):
    """Compose the YAML, check its expanded size, then build the Python data."""
    loader = _Loader(text)
    try:
        node = loader.get_single_node()
        _check_size(node)
        return loader.construct_document(node) if node is not None else None
    finally:
        loader.dispose()


MAX_NODES = 100_000  # values in a config once aliases are expanded: real ones have a few hundred


def _check_size(root):
    """Refuse YAML whose aliases expand to more than MAX_NODES values (a "billion laughs" bomb
    composes in a few nodes but expands exponentially where the config is hashed or printed) or
    refer to themselves. Counted on the composed nodes, each node once: time and memory stay linear."""
    sizes, open_nodes = {}, set()

    def size(node):
        if id(node) in sizes:
            return sizes[id(node)]
        if id(node) in open_nodes:
            raise ConfigError("", "YAML alias refers to itself (a recursive structure)")
        open_nodes.add(id(node))
        children = node.value if isinstance(node, yaml.SequenceNode) else \
            [n for pair in node.value for n in pair] if isinstance(node, yaml.MappingNode) else []
        total = 1 + sum(size(child) for child in children)
        if total > MAX_NODES:
            raise ConfigError("", f"YAML expands to more than {MAX_NODES} values (aliases of aliases?)")
        open_nodes.discard(id(node))
        sizes[id(node)] = total
        return total

    if root is not None:
        size(root)
