"""Load a module of py/yadecd from its file, without importing the yadecd package (whose
__init__ needs YADE), under the name ``_yadecd_<stem>`` that the analysis modules share
(pile_figures finds pile_analysis there). Used by the tests that run without YADE too."""
import importlib.util
import os
import sys

PKG = os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', 'py', 'yadecd')


def load(stem):
    """The module py/yadecd/<stem>.py, loaded once."""
    name = '_yadecd_' + stem
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, os.path.join(PKG, stem + '.py'))
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]
