; plus1: z = x + 1.0 at one iteration per cycle (II 1, 5 stages). x lands 3 cycles after
; its read and the add reads it a cycle later, just as the next iteration's x lands. Modulo
; variable expansion (Lam 1988): two copies of the kernel alternate `add0.a[0]` and
; `add0.a[1]`, so each x is overwritten only 2 cycles after it landed. The loop may leave
; after either copy, in the middle of the body when the iteration count is odd.
kernel plus1
in x
out z
    imm 1.0 -> add0.b[0]
loop stream x, stages 5:
    sin0 x -> add0.a[0] | add0 fadd a[0], b[0] -> stream z @4
pass
    sin0 x -> add0.a[1] | add0 fadd a[1], b[0] -> stream z @4
end
done
