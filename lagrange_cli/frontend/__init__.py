"""The frontend: a system file (YAML) in, a validated `SystemSpec` of sympy expressions out.

- `source`: composing the YAML (limits, tags) and where each node is written (file:line:col);
- `nodes`: the node types of a validated file (frozen dataclasses, no YAML);
- `core`: what the section readers share (problems, maps, lists, names, numbers, expressions);
- `declarations`, `mechanics`, `runs`, `checks`: the section readers, one group of sections each;
- `reader`: the whole file, section by section;
- `files`: finding, naming, reading and validating a system file.

`lagrange_cli.spec` is the public entry point and re-exports what users and tests import.
"""
