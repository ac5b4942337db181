"""Humanoid balance tasks on the humanoid scene shipped with mpcbox."""
