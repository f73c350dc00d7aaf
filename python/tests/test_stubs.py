"""The type stubs (idexp/_idexp.pyi) cover the native module: every public
class member and function, with the module's parameter names in order."""

import ast
import inspect
import pathlib

import idexp

STUB = pathlib.Path(__file__).resolve().parents[1] / "idexp" / "_idexp.pyi"


def stub_tree():
    tree = ast.parse(STUB.read_text())
    classes, functions = {}, {}
    for node in tree.body:
        if isinstance(node, ast.ClassDef):
            members = {}
            for b in node.body:
                if isinstance(b, ast.FunctionDef):
                    members[b.name] = b
                elif isinstance(b, ast.AnnAssign) and isinstance(b.target, ast.Name):
                    members[b.target.id] = None
            classes[node.name] = members
        elif isinstance(node, ast.FunctionDef):
            functions[node.name] = node
    return classes, functions


def stub_params(fn, method):
    names = [a.arg for a in fn.args.args + fn.args.kwonlyargs]
    return names[1:] if method and names and names[0] in ("self",) else names


def native_params(obj):
    return [p for p in inspect.signature(obj).parameters if p not in ("self", "$self")]


def test_every_public_name_is_in_the_stubs():
    classes, functions = stub_tree()
    for name in idexp.__all__:
        obj = getattr(idexp, name)
        if inspect.isclass(obj) and not issubclass(obj, BaseException):
            assert name in classes, f"class {name} missing from {STUB.name}"
            for member in (m for m in vars(obj) if not m.startswith("_")):
                assert member in classes[name], f"{name}.{member} missing from {STUB.name}"
                fn = classes[name][member]
                if fn is not None and callable(getattr(obj, member)) and not isinstance(vars(obj)[member], property):
                    want = native_params(getattr(obj, member))
                    assert stub_params(fn, method=not isinstance(vars(obj)[member], staticmethod)) == want, \
                        f"{name}.{member}: stub parameters differ from the module's {want}"
        elif callable(obj) and not inspect.isclass(obj):
            assert name in functions, f"function {name} missing from {STUB.name}"
            assert stub_params(functions[name], method=False) == native_params(obj), name
