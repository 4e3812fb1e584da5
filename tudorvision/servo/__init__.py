"""tudorvision.servo"""
__all__: list[str] = []
