error: systems/central_potential.yaml: Python code needs every function defined, but U is left undefined; write it out as an expression in the system file
