"""The .pyi stub names everything the module exports (editors complete what exists)."""

import ast
import pathlib

import rangebayes as rb


def test_stub_lists_every_public_name():
    stub = pathlib.Path(rb.__file__).with_name("__init__.pyi")
    tree = ast.parse(stub.read_text())
    names = set()
    for node in tree.body:
        if isinstance(node, (ast.ClassDef, ast.FunctionDef)):
            names.add(node.name)
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            names.add(node.target.id)
        elif isinstance(node, ast.Assign):
            names.update(t.id for t in node.targets if isinstance(t, ast.Name))
    public = {n for n in dir(rb._rangebayes) if not n.startswith("_")} | {"to_open3d", "from_open3d"}
    assert public - names == set()


def test_stub_classes_list_every_attribute():
    """Each class of the stub lists the attributes the bound class has (dir(), without methods)."""
    stub = pathlib.Path(rb.__file__).with_name("__init__.pyi")
    missing = {}
    for node in ast.parse(stub.read_text()).body:
        if not isinstance(node, ast.ClassDef) or not hasattr(rb._rangebayes, node.name):
            continue
        listed = {item.target.id for item in node.body if isinstance(item, ast.AnnAssign)}
        listed |= {item.name for item in node.body if isinstance(item, ast.FunctionDef)}
        cls = getattr(rb._rangebayes, node.name)
        bound = {n for n, v in vars(cls).items() if not n.startswith("_") and isinstance(v, property)}
        if bound - listed:
            missing[node.name] = sorted(bound - listed)
    assert missing == {}
