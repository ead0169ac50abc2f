"""What the three-limb translational parallel robots (the 3-[P2(US)], the Delta) share: the
design's limb geometry and checks (`params`), the assembly of per-limb IK roots into the 8
working modes and the velocity matrices (`modes`), the URDF tree, loop sidecar and their
writing (`urdf`), reading a design back (`reader`), and the `Mechanism` methods that only
forward to a family's closed forms (`mechanism`). Forward kinematics as three spheres'
intersection, with the working-mode labels, is `closed_form`.
"""
