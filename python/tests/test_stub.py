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
