"""Forms compiled once per process: FFCx's JIT searches its cache folder again for every form, element
and expression a level builds (listing the whole folder each time); the points of a map build the same
forms over and over, so a module once found is kept in memory."""
import contextlib

from ffcx.codegeneration import jit as ffcx_jit


@contextlib.contextmanager
def kept():
    """Within: a JIT module found in FFCx's cache is looked up there once; FFCx's own lookup after."""
    original = ffcx_jit.get_cached_module
    found = {}

    def cached(module_name, object_names, cache_dir, timeout):
        key = (module_name, tuple(object_names), str(cache_dir))
        if key not in found:
            objects, module = original(module_name, object_names, cache_dir, timeout)
            if module is None:  # not compiled yet: FFCx compiles it now, and finds it the next time
                return objects, module
            found[key] = (objects, module)
        return found[key]

    ffcx_jit.get_cached_module = cached
    try:
        yield
    finally:
        ffcx_jit.get_cached_module = original
