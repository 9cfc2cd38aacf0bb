"""The statistical head model: PCA, the linear model every fit works on, and the bundled head
(mesh, identity and expression modes, regions, landmarks)."""
